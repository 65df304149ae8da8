//! Client jobs: an F the caller evaluates, a batch of points at a time (ask/tell), played by
//! the test as a client would, against the real server.

use crate::helpers::{TestApp, read_events, spawn_app};
use serde_json::{Value, json};

/// The caller's F, and the same as an expression the server evaluates itself: sums and
/// products alone, which both compute to the same bits.
fn f(x: f64, y: f64) -> f64 {
    x * y * y - 0.5 * x + y
}
const EXPRESSION: &str = "x*y*y - 0.5*x + y";

/// Makes a client job of `body`: its id and status document.
async fn create(app: &TestApp, body: Value) -> (String, Value) {
    let response = app.post("/v1/jobs", &body).await;
    assert_eq!(response.status(), 202, "{body}");
    let location = response.headers()["location"].to_str().unwrap().to_owned();
    let status: Value = response.json().await.unwrap();
    assert_eq!(location, format!("/v1/jobs/{}", status["id"].as_str().unwrap()));
    (status["id"].as_str().unwrap().to_owned(), status)
}

/// The values of `points` as a tell's body, F from `value`.
fn told(points: &Value, value: impl Fn(f64, f64) -> Option<f64>) -> Value {
    let values: Vec<Value> = (points.as_array().unwrap().iter())
        .map(|p| json!({"id": p["id"], "value": value(p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap())}))
        .collect();
    json!({"values": values})
}

/// Asks and tells until the job finishes: how many batches it asked.
async fn play(app: &TestApp, id: &str, value: impl Fn(f64, f64) -> Option<f64>) -> usize {
    let (mut batches, mut last) = (0, 0);
    loop {
        let response = app.get(&format!("/v1/jobs/{id}/ask?wait=9000")).await;
        if response.status() == 204 {
            continue;
        }
        assert_eq!(response.status(), 200);
        let ask: Value = response.json().await.unwrap();
        if ask["status"] != "running" {
            assert_eq!(ask["points"], json!([]), "{ask}");
            return batches;
        }
        batches += 1;
        let number = ask["batch"].as_u64().unwrap();
        assert!(number > last, "batches are numbered in order: {ask}");
        last = number;
        let response = app.post(&format!("/v1/jobs/{id}/tell"), &told(&ask["points"], &value)).await;
        assert_eq!(response.status(), 200);
    }
}

#[tokio::test]
async fn a_client_job_asked_and_told_makes_the_mesh_the_server_makes_of_the_same_f() {
    let app = spawn_app().await;
    let body =
        json!({"source": "client", "domain": {"x": [-1, 2], "y": [0, 1]}, "max_vertices": 400, "batch": 8});
    let (id, status) = create(&app, body).await;
    assert_eq!(status["status"], "running");
    assert_eq!(status["evaluations"], json!({"asked": 4, "told": 0, "pending": 4, "failed": 0}));
    assert_eq!(status["links"]["ask"], format!("/v1/jobs/{id}/ask"));
    assert_eq!(status["links"]["events"], format!("/v1/jobs/{id}/events"), "{status}");
    let batches = play(&app, &id, |x, y| Some(f(x, y))).await;
    let done: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    assert_eq!(done["status"], "succeeded", "{done}");
    let evaluations = &done["evaluations"];
    let (asked, told) = (evaluations["asked"].as_u64().unwrap(), evaluations["told"].as_u64().unwrap());
    assert_eq!((asked, evaluations["pending"].as_u64()), (told, Some(0)), "{done}");
    // The corners, then at most 8 a batch; the mesh used 400 of the points.
    let midpoints = 400 - 4;
    assert!(batches as u64 > midpoints / 8 && asked >= 400, "{batches} batches, {asked} points");
    assert_eq!(done["stats"]["vertices"], 400);
    assert_eq!(done["stats"]["evaluations"], 400, "the mesh's own evaluations, one a vertex");
    // The same mesh, bit for bit, as the server's own run of the same F by the client job's
    // default criterion.
    let mine: Value = app.get(&format!("/v1/jobs/{id}/mesh")).await.json().await.unwrap();
    let theirs: Value = (app.post(
        "/v1/meshes",
        &json!({"function": EXPRESSION, "domain": {"x": [-1, 2], "y": [0, 1]},
        "max_vertices": 400, "criterion": "curvature"}),
    ))
    .await
    .json()
    .await
    .unwrap();
    assert_eq!(mine["vertices"], theirs["vertices"]);
    assert_eq!(mine["triangles"], theirs["triangles"]);
    // F_n at a point, as any job's.
    let at: Value = app
        .post(&format!("/v1/jobs/{id}/evaluate"), &json!({"points": [[0.5, 0.5]]}))
        .await
        .json()
        .await
        .unwrap();
    assert!((at["values"][0].as_f64().unwrap() - f(0.5, 0.5)).abs() < 1e-2, "{at}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_caller_can_play_from_the_event_stream_alone() {
    let app = spawn_app().await;
    let (id, _) = create(&app, json!({"source": "client", "max_vertices": 80, "batch": 4})).await;
    let listed = |status: &'static str| {
        let (app, id) = (&app, id.clone());
        async move {
            let list: Value = app.get(&format!("/v1/jobs?status={status}")).await.json().await.unwrap();
            list["jobs"].as_array().unwrap().iter().find(|j| j["id"] == id.as_str()).cloned()
        }
    };
    // The caller's job list shows it as any job, with its evaluations.
    let running = listed("running").await.expect("a running client job is listed");
    assert_eq!(running["evaluations"]["pending"], 4, "{running}");
    let mut stream = app.client.get(app.url(&format!("/v1/jobs/{id}/events"))).send().await.unwrap();
    assert_eq!(stream.headers()["content-type"], "text/event-stream");
    let (mut pending, mut asks) = (String::new(), Vec::new());
    // Reads events as they come and tells each batch's points, no ask requests at all.
    let result = 'stream: loop {
        let chunk = stream.chunk().await.unwrap().expect("the stream ends after its result event");
        pending.push_str(std::str::from_utf8(&chunk).unwrap());
        while let Some(end) = pending.find("\n\n") {
            let block: String = pending.drain(..end + 2).collect();
            let field =
                |name: &str| block.lines().find_map(|l| l.strip_prefix(name)).map(|v| v.trim().to_owned());
            let (Some(event), Some(event_id), Some(data)) = (field("event:"), field("id:"), field("data:"))
            else {
                continue; // a keep-alive comment
            };
            let event_id: u64 = event_id.parse().unwrap();
            let data: Value = serde_json::from_str(&data).unwrap();
            if event != "ask" {
                break 'stream (event, event_id, data);
            }
            assert_eq!(data["batch"], event_id, "{data}");
            assert!(data["lease_ms"].as_u64().is_some() && !data["points"].as_array().unwrap().is_empty());
            let response =
                app.post(&format!("/v1/jobs/{id}/tell"), &told(&data["points"], |x, y| Some(f(x, y)))).await;
            assert_eq!(response.status(), 200);
            asks.push(event_id);
        }
    };
    // Every batch, in order, from the corners on: a batch is chosen only once the last is told.
    assert_eq!(asks, (1..=asks.len() as u64).collect::<Vec<_>>());
    let (event, event_id, data) = result;
    assert_eq!((event.as_str(), event_id), ("result", asks.len() as u64 + 1), "{data}");
    assert_eq!(data["status"], "succeeded");
    assert_eq!(data["stats"]["vertices"], 80);
    assert!(listed("running").await.is_none());
    let succeeded = listed("succeeded").await.expect("a finished client job is listed");
    assert_eq!(succeeded["stats"]["vertices"], 80, "{succeeded}");
    // A listener that saw the end is told so; one that saw nothing gets the end at once, with
    // the mesh inline if it asks.
    let seen = app
        .client
        .get(app.url(&format!("/v1/jobs/{id}/events")))
        .header("last-event-id", event_id.to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(seen.status(), 204);
    let late = read_events(app.get(&format!("/v1/jobs/{id}/events?inline=mesh")).await).await;
    assert_eq!(late.len(), 1, "{late:?}");
    let mesh: Value = serde_json::from_str(&late[0].data).unwrap();
    assert_eq!((late[0].event.as_str(), mesh["vertices"].as_array().unwrap().len()), ("result", 80));
    app.shutdown().await;
}

#[tokio::test]
async fn tells_are_checked_point_by_point_and_a_repeat_is_a_no_op() {
    let app = spawn_app().await;
    let (id, _) = create(&app, json!({"source": "client", "max_vertices": 50})).await;
    let ask: Value = app.get(&format!("/v1/jobs/{id}/ask")).await.json().await.unwrap();
    let tell = |body: Value| {
        let (app, id) = (&app, id.clone());
        async move { app.post(&format!("/v1/jobs/{id}/tell"), &body).await }
    };
    // Not finished: no mesh, no point values.
    assert_eq!(app.get(&format!("/v1/jobs/{id}/mesh")).await.status(), 409);
    let at = app.post(&format!("/v1/jobs/{id}/evaluate"), &json!({"points": [[0.5, 0.5]]})).await;
    assert_eq!(at.status(), 409);
    // A value left out (rather than null) is no tell.
    let response = tell(json!({"values": [{"id": 0}]})).await;
    assert_eq!(response.status(), 422);
    // An id never asked: 422 naming the entry, and nothing told.
    let response = tell(json!({"values": [{"id": 0, "value": 1.0}, {"id": 99, "value": 1.0}]})).await;
    assert_eq!(response.status(), 422);
    let p: Value = response.json().await.unwrap();
    assert_eq!(p["field"], "/values/1/id", "{p}");
    let status: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    assert_eq!(status["evaluations"]["told"], 0, "all or none: {status}");
    // A value, the same again (a no-op), then a different one (409 naming it).
    let first = tell(json!({"values": [{"id": 0, "value": 1.5}]})).await;
    assert_eq!(first.json::<Value>().await.unwrap()["accepted"], 1);
    let again = tell(json!({"values": [{"id": 0, "value": 1.5}]})).await;
    assert_eq!(again.status(), 200);
    assert_eq!(again.json::<Value>().await.unwrap()["accepted"], 0);
    let other = tell(json!({"values": [{"id": 0, "value": 2.5}]})).await;
    assert_eq!(other.status(), 409);
    let p: Value = other.json().await.unwrap();
    assert_eq!(
        (p["field"].as_str(), p["type"].as_str()),
        (Some("/values/0/value"), Some("/problems/conflicting-value"))
    );
    assert!(p["detail"].as_str().unwrap().contains("point 0 was told 1.5, not 2.5"), "{p}");
    // A failed point (null) counts as failed; the rest completes the corners' batch.
    let rest = told(&ask["points"], |x, y| if x == 0.0 && y == 0.0 { None } else { Some(x + y) });
    let rest: Vec<Value> =
        rest["values"].as_array().unwrap().iter().filter(|v| v["id"] != 0).cloned().collect();
    let response = tell(json!({"values": rest})).await;
    let answer: Value = response.json().await.unwrap();
    assert_eq!(answer["evaluations"]["told"], 4, "{answer}");
    // Bad requests name their field.
    for (body, field) in [
        (json!({"source": "client", "criterion": "error"}), "/criterion"),
        (json!({"source": "client", "batch": 0}), "/batch"),
        (json!({"source": "client", "lease_ms": 5}), "/lease_ms"),
        (json!({"source": "client", "method": "data-dependent"}), "/method"),
        (json!({"source": "server"}), "/source"),
        (json!({"source": "client", "function": "x"}), "/function"),
        (json!({"source": "client", "from": "0".repeat(64)}), "/from"),
        (json!({"source": "client", "on_failure": "retry"}), "/on_failure"),
    ] {
        let response = app.post("/v1/jobs", &body).await;
        assert_eq!(response.status(), 422, "{body}");
        let problem: Value = response.json().await.unwrap();
        assert_eq!(
            (&problem["field"], &problem["type"]),
            (&json!(field), &json!("/problems/invalid-request")),
            "{body}"
        );
    }
    assert_eq!(app.get(&format!("/v1/jobs/{id}/ask?wait=10000")).await.status(), 422);
    assert_eq!(app.get(&format!("/v1/jobs/{}/ask", "0".repeat(64))).await.status(), 404);
    app.shutdown().await;
}

#[tokio::test]
async fn a_batch_leased_and_not_told_is_offered_again_and_a_failed_point_keeps_the_job_going() {
    let app = spawn_app().await;
    let (id, _) =
        create(&app, json!({"source": "client", "max_vertices": 40, "batch": 4, "lease_ms": 100})).await;
    let first: Value = app.get(&format!("/v1/jobs/{id}/ask")).await.json().await.unwrap();
    // Leased to the first asker: a second one waiting no time gets nothing, and when to retry.
    let busy = app.get(&format!("/v1/jobs/{id}/ask")).await;
    assert_eq!(busy.status(), 204);
    assert!(busy.headers().contains_key("retry-after"));
    // The first asker is lost: past the lease, a waiting asker gets the same batch.
    let again: Value = app.get(&format!("/v1/jobs/{id}/ask?wait=9000")).await.json().await.unwrap();
    assert_eq!((&again["batch"], &again["points"]), (&first["batch"], &first["points"]));
    // One point of every batch fails; the job still finishes, counting them.
    let failing = |x: f64, y: f64| if x > 0.0 && x < 1.0 && y == 0.0 { None } else { Some(f(x, y)) };
    let response = app.post(&format!("/v1/jobs/{id}/tell"), &told(&again["points"], failing)).await;
    assert_eq!(response.status(), 200);
    play(&app, &id, failing).await;
    let done: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    assert_eq!(done["status"], "succeeded", "{done}");
    assert!(done["evaluations"]["failed"].as_u64().unwrap() >= 1, "{done}");
    assert_eq!(done["stats"]["vertices"], 40);
    app.shutdown().await;
}

#[tokio::test]
async fn a_cancelled_client_job_asks_for_nothing_more() {
    let app = spawn_app().await;
    let (id, _) = create(&app, json!({"source": "client"})).await;
    let response = app.delete(&format!("/v1/jobs/{id}")).await;
    assert_eq!(response.json::<Value>().await.unwrap()["status"], "cancelled");
    let ask: Value = app.get(&format!("/v1/jobs/{id}/ask")).await.json().await.unwrap();
    assert_eq!(ask, json!({"status": "cancelled", "points": []}));
    let mesh = app.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(mesh.status(), 409);
    app.shutdown().await;
}

#[tokio::test]
async fn a_job_from_another_reuses_its_values_asking_only_for_new_points() {
    let app = spawn_app().await;
    let job = |vertices: u64| json!({"source": "client", "max_vertices": vertices, "batch": 8});
    let (big, _) = create(&app, job(300)).await;
    play(&app, &big, |x, y| Some(f(x, y))).await;
    let mesh = |id: String| {
        let app = &app;
        async move {
            let response = app.get(&format!("/v1/jobs/{id}/mesh")).await;
            assert_eq!(response.status(), 200);
            let mut mesh: Value = response.json().await.unwrap();
            assert_eq!(mesh["id"].take(), json!(id));
            mesh
        }
    };

    // A smaller budget is a prefix of the run: it finishes without asking for anything.
    let mut smaller = job(120);
    smaller["from"] = json!(big);
    let (small, status) = create(&app, smaller).await;
    assert_eq!(status["evaluations"]["asked"], 0, "{status}");
    assert_eq!(play(&app, &small, |_, _| panic!("nothing is asked")).await, 0);
    let (fresh, _) = create(&app, job(120)).await;
    play(&app, &fresh, |x, y| Some(f(x, y))).await;
    assert!(mesh(small.clone()).await == mesh(fresh).await, "the mesh a fresh run of the budget makes");

    // A larger one asks only for what the first was not told.
    let mut larger = job(400);
    larger["from"] = json!(small);
    let (larger, _) = create(&app, larger).await;
    play(&app, &larger, |x, y| Some(f(x, y))).await;
    let done: Value = app.get(&format!("/v1/jobs/{larger}")).await.json().await.unwrap();
    assert_eq!(done["stats"]["vertices"], 400, "{done}");
    let asked = done["evaluations"]["asked"].as_u64().unwrap();
    assert!((100..300).contains(&asked), "about 100 new points, not 400: {asked}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_tell_with_ask_brings_the_next_batch_back_one_request_a_batch() {
    let app = spawn_app().await;
    let body = json!({"source": "client", "max_vertices": 120, "batch": 8});
    let (id, _) = create(&app, body.clone()).await;
    let mut ask: Value = app.get(&format!("/v1/jobs/{id}/ask")).await.json().await.unwrap();
    let mut requests = 0;
    while ask["status"] == "running" {
        let values = told(&ask["points"], |x, y| Some(f(x, y)));
        let response = app.post(&format!("/v1/jobs/{id}/tell?ask=9000"), &values).await;
        assert_eq!(response.status(), 200);
        let answer: Value = response.json().await.unwrap();
        ask = answer["next"].clone();
        assert!(ask["points"].is_array(), "the next batch (or the end) came back: {answer}");
        requests += 1;
    }
    assert_eq!((&ask["status"], &ask["points"]), (&json!("succeeded"), &json!([])));
    // A tell without `ask` answers no `next`; a wait past the longest is refused.
    let again =
        app.post(&format!("/v1/jobs/{id}/tell"), &json!({"values": [{"id": 0, "value": f(0.0, 0.0)}]})).await;
    assert_eq!(again.json::<Value>().await.unwrap().get("next"), None);
    let long = app.post(&format!("/v1/jobs/{id}/tell?ask=9001"), &json!({"values": []})).await;
    assert_eq!(long.status(), 422);

    // The same values played with two requests a batch make the same batches and mesh.
    let (other, _) = create(&app, body).await;
    assert_eq!(play(&app, &other, |x, y| Some(f(x, y))).await, requests);
    let mesh = |id: String| {
        let app = &app;
        async move {
            let mut mesh: Value = app.get(&format!("/v1/jobs/{id}/mesh")).await.json().await.unwrap();
            mesh["id"].take();
            mesh
        }
    };
    assert!(mesh(id).await == mesh(other).await);
    app.shutdown().await;
}

#[tokio::test]
async fn a_job_made_to_fail_on_a_failed_point_fails_naming_it() {
    let app = spawn_app().await;
    let (id, _) = create(&app, json!({"source": "client", "max_vertices": 40, "on_failure": "fail"})).await;
    let ask: Value = app.get(&format!("/v1/jobs/{id}/ask")).await.json().await.unwrap();
    let values = told(&ask["points"], |x, y| Some(f(x, y)));
    app.post(&format!("/v1/jobs/{id}/tell"), &values).await;
    let ask: Value = app.get(&format!("/v1/jobs/{id}/ask?wait=9000")).await.json().await.unwrap();
    let points = ask["points"].as_array().unwrap();
    let (bad, x, y) = (&points[1]["id"], points[1]["x"].as_f64().unwrap(), points[1]["y"].as_f64().unwrap());
    // Two fail at once: the job names the first.
    let values = json!({"values": [
        {"id": points[0]["id"], "value": 1.0},
        {"id": bad, "value": null, "reason": "diverged"},
        {"id": points[2]["id"], "value": null},
    ]});
    let answer: Value = app.post(&format!("/v1/jobs/{id}/tell"), &values).await.json().await.unwrap();
    assert_eq!(answer["status"], "failed", "{answer}");
    let status: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    let problem = &status["problem"];
    assert_eq!(problem["type"], "/problems/client-job-failed", "{status}");
    let named = format!("point {bad} at ({x}, {y}) failed");
    assert!(problem["detail"].as_str().unwrap().starts_with(&named), "{problem}");
    assert_eq!(status["evaluations"]["failed"], 2);
    let ask: Value = app.get(&format!("/v1/jobs/{id}/ask")).await.json().await.unwrap();
    assert_eq!(ask, json!({"status": "failed", "points": []}));
    app.shutdown().await;
}
