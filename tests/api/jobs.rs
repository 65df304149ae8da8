//! Meshes and jobs: results, ids, the cache, joining, cancellation, the queue.

use crate::helpers::spawn_app;
use serde_json::{Value, json};
use std::time::Duration;

#[tokio::test]
async fn post_meshes_returns_the_mesh_document_with_its_id_as_etag() {
    let app = spawn_app().await;
    let response = app.post("/v1/meshes", &json!({"function": "sin(x)*cos(y)", "max_vertices": 500})).await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "application/json");
    assert_eq!(response.headers()["x-cache"], "miss");
    let etag = response.headers()["etag"].to_str().unwrap().to_owned();
    let doc: Value = response.json().await.unwrap();
    assert_eq!(etag, format!("\"{}\"", doc["id"].as_str().unwrap()));
    assert_eq!(doc["id"].as_str().unwrap().len(), 64);
    assert_eq!(doc["vertices"].as_array().unwrap().len(), 500);
    assert_eq!(doc["stats"]["vertices"], 500);
    assert_eq!(doc["stats"]["delaunay"], true);
    let triangles = doc["triangles"].as_array().unwrap();
    assert_eq!(doc["stats"]["triangles"].as_u64().unwrap() as usize, triangles.len());
    // The corner P3 = (1, 1) carries F(1, 1).
    assert_eq!(doc["vertices"][2], json!([1.0, 1.0, 1f64.sin() * 1f64.cos()]));
    app.shutdown().await;
}

#[tokio::test]
async fn a_repeated_request_is_a_cache_hit_with_the_same_id_and_bytes() {
    let app = spawn_app().await;
    let body = json!({"function": "x^2 - y", "max_vertices": 2000, "method": "recursive"});
    let first = app.post("/v1/meshes", &body).await;
    let first_etag = first.headers()["etag"].clone();
    let first_bytes = first.bytes().await.unwrap();
    let second = app.post("/v1/meshes", &body).await;
    assert_eq!(second.headers()["x-cache"], "hit");
    assert_eq!(second.headers()["etag"], first_etag);
    assert_eq!(second.bytes().await.unwrap(), first_bytes, "byte-identical body");
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 1.0);
    assert_eq!(app.metric("meshfit_cache_hits_total").await, 1.0);
    app.shutdown().await;
}

#[tokio::test]
async fn key_order_number_spelling_and_defaults_do_not_change_the_id() {
    let app = spawn_app().await;
    let id = |doc: Value| doc["id"].as_str().unwrap().to_owned();
    let short: Value =
        app.post("/v1/meshes", &json!({"function": "x*y", "tolerance": 1})).await.json().await.unwrap();
    let spelled_out = r#"{"tolerance": 1.0, "criterion": "error", "method": "semi-recursive",
        "domain": {"y": [0, 1.0], "x": [0.0, 1]}, "max_vertices": 1e4, "function": "x*y"}"#;
    let long: Value = app.post_raw("/v1/meshes", spelled_out).await.json().await.unwrap();
    assert_eq!(id(short.clone()), id(long));
    let other: Value = app
        .post("/v1/meshes", &json!({"function": "x*y", "tolerance": 1, "max_vertices": 9999}))
        .await
        .json()
        .await
        .unwrap();
    assert_ne!(id(short), id(other), "a different budget is a different job");
    app.shutdown().await;
}

#[tokio::test]
async fn if_none_match_with_the_etag_answers_304() {
    let app = spawn_app().await;
    let body = json!({"function": "x+y", "max_vertices": 50});
    let etag = app.post("/v1/meshes", &body).await.headers()["etag"].clone();
    let again = app
        .client
        .post(app.url("/v1/meshes"))
        .json(&body)
        .header("if-none-match", etag.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(again.status(), 304);
    assert!(again.bytes().await.unwrap().is_empty());
    let id = etag.to_str().unwrap().trim_matches('"').to_owned();
    let mesh = app
        .client
        .get(app.url(&format!("/v1/jobs/{id}/mesh")))
        .header("if-none-match", etag)
        .send()
        .await
        .unwrap();
    assert_eq!(mesh.status(), 304);
    app.shutdown().await;
}

#[tokio::test]
async fn a_job_is_accepted_then_reports_its_status_and_serves_its_mesh() {
    let app = spawn_app().await;
    let body = json!({"function": "exp(-10*((x-0.3)^2+(y-0.6)^2))", "max_vertices": 20000});
    let created = app.post("/v1/jobs", &body).await;
    assert_eq!(created.status(), 202);
    let retry: u64 = created.headers()["retry-after"].to_str().unwrap().parse().unwrap();
    assert!(retry >= 1, "a 202 says when to look again");
    let location = created.headers()["location"].to_str().unwrap().to_owned();
    let status: Value = created.json().await.unwrap();
    let id = status["id"].as_str().unwrap().to_owned();
    assert_eq!(location, format!("/v1/jobs/{id}"));
    assert!(matches!(status["status"].as_str(), Some("queued" | "running")), "{status}");
    assert_eq!(status["links"]["mesh"], format!("/v1/jobs/{id}/mesh"));

    let done = app.wait_finished(&id).await;
    assert_eq!(done["status"], "succeeded");
    assert_eq!(done["stats"]["vertices"], 20000);
    // RFC 3339 times, which sort as text: made, then started, then finished.
    let time = |key: &str| done[key].as_str().unwrap_or_else(|| panic!("{key} in {done}")).to_owned();
    let (made, started, finished) = (time("created_at"), time("started_at"), time("finished_at"));
    assert!(made.ends_with('Z') && made <= started && started <= finished, "{done}");
    let mesh = app.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(mesh.status(), 200);
    let mesh: Value = mesh.json().await.unwrap();
    assert_eq!(mesh["stats"], done["stats"]);
    // Submitting it again finds the finished job: 200, not 202.
    assert_eq!(app.post("/v1/jobs", &body).await.status(), 200);
    // The synchronous endpoint serves the same document from the cache.
    let sync = app.post("/v1/meshes", &body).await;
    assert_eq!(sync.headers()["x-cache"], "hit");
    assert_eq!(sync.json::<Value>().await.unwrap(), mesh);
    app.shutdown().await;
}

#[tokio::test]
async fn unknown_jobs_are_404_and_unfinished_meshes_are_409() {
    let app = spawn_app().await;
    let unknown = "0".repeat(64);
    for path in [
        format!("/v1/jobs/{unknown}"),
        format!("/v1/jobs/{unknown}/mesh"),
        format!("/v1/jobs/{unknown}/events"),
    ] {
        let response = app.get(&path).await;
        assert_eq!(response.status(), 404, "{path}");
        assert_eq!(response.headers()["content-type"], "application/problem+json");
    }
    assert_eq!(app.delete(&format!("/v1/jobs/{unknown}")).await.status(), 404);

    let status: Value = app
        .post("/v1/jobs", &json!({"function": "sin(40*x*y)", "max_vertices": 2_000_000}))
        .await
        .json()
        .await
        .unwrap();
    let id = status["id"].as_str().unwrap();
    let mesh = app.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(mesh.status(), 409);
    assert!(mesh.headers().contains_key("retry-after"), "a 409 says when to look again");
    let problem: Value = mesh.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/not-finished");
    app.delete(&format!("/v1/jobs/{id}")).await;
    app.shutdown().await;
}

#[tokio::test]
async fn concurrent_identical_requests_run_the_engine_once() {
    let app = spawn_app().await;
    let body = json!({"function": "sin(7*x)*cos(5*y)", "max_vertices": 300_000});
    let requests = (0..4).map(|_| app.post("/v1/meshes", &body));
    let responses = futures_util::future::join_all(requests).await;
    let mut bodies = Vec::new();
    for r in responses {
        assert_eq!(r.status(), 200);
        bodies.push(r.bytes().await.unwrap());
    }
    assert!(bodies.windows(2).all(|w| w[0] == w[1]), "every client gets the same document");
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 1.0);
    app.shutdown().await;
}

#[tokio::test]
async fn delete_stops_a_running_job_and_answers_with_its_final_state() {
    let app = spawn_app().await;
    let status: Value = app
        .post("/v1/jobs", &json!({"function": "sin(30*x)*cos(30*y)", "max_vertices": 2_000_000}))
        .await
        .json()
        .await
        .unwrap();
    let id = status["id"].as_str().unwrap().to_owned();
    app.wait_running(&id).await;
    let cancelled = app.delete(&format!("/v1/jobs/{id}")).await;
    assert_eq!(cancelled.status(), 200);
    let cancelled: Value = cancelled.json().await.unwrap();
    // The answer waits for the worker to stop: the state is final, and no worker is busy.
    assert_eq!(cancelled["status"], "cancelled");
    assert_eq!(app.metric("meshfit_jobs_running").await, 0.0);
    assert_eq!(app.metric("meshfit_jobs_finished_total{state=\"cancelled\"}").await, 1.0);
    let mesh = app.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(mesh.status(), 409, "a cancelled job has no mesh");
    app.shutdown().await;
}

#[tokio::test]
async fn a_client_that_hangs_up_cancels_its_synchronous_job() {
    let app = spawn_app().await;
    let impatient = reqwest::Client::builder().timeout(Duration::from_millis(300)).build().unwrap();
    let body = json!({"function": "sin(33*x)*cos(31*y)", "max_vertices": 2_000_000});
    let result = impatient.post(app.url("/v1/meshes")).json(&body).send().await;
    assert!(result.is_err(), "the request should time out on the client side");
    for _ in 0..100 {
        if app.metric("meshfit_jobs_finished_total{state=\"cancelled\"}").await == 1.0 {
            app.shutdown().await;
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    panic!("the job was not cancelled after its client left");
}

#[tokio::test]
async fn a_full_queue_answers_503_with_retry_after_while_healthz_still_answers() {
    let mut config = crate::helpers::test_config();
    config.pool.workers = std::num::NonZeroUsize::new(1).unwrap();
    config.pool.queue = 1;
    let app = crate::helpers::spawn_with(config).await;
    let job = |k: u32| json!({"function": format!("sin({k}*x)*cos(y)"), "max_vertices": 2_000_000});
    let running: Value = app.post("/v1/jobs", &job(11)).await.json().await.unwrap();
    app.wait_running(running["id"].as_str().unwrap()).await;
    let queued: Value = app.post("/v1/jobs", &job(12)).await.json().await.unwrap();
    assert_eq!(queued["status"], "queued");

    let refused = app.post("/v1/jobs", &job(13)).await;
    assert_eq!(refused.status(), 503);
    assert_eq!(refused.headers()["retry-after"], "1");
    let problem: Value = refused.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/queue-full");
    assert_eq!(app.get("/readyz").await.status(), 503);

    // Liveness is not readiness: a full queue leaves the process alive.
    assert_eq!(app.get("/healthz").await.status(), 200);

    for status in [running, queued] {
        app.delete(&format!("/v1/jobs/{}", status["id"].as_str().unwrap())).await;
    }
    assert_eq!(app.get("/readyz").await.status(), 200);
    app.shutdown().await;
}

#[tokio::test]
async fn f_not_finite_fails_the_job_with_the_point() {
    let app = spawn_app().await;
    let response = app.post("/v1/meshes", &json!({"function": "1/(x - 0.5)"})).await;
    assert_eq!(response.status(), 422);
    let problem: Value = response.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/non-finite-value");
    assert_eq!(problem["point"][0], 0.5);
    // The job's status carries the same problem.
    let status: Value = app.post("/v1/jobs", &json!({"function": "1/(x - 0.5)"})).await.json().await.unwrap();
    assert_eq!(status["status"], "failed");
    assert_eq!(status["problem"]["point"], problem["point"]);
    app.shutdown().await;
}

#[tokio::test]
async fn a_cancelled_job_runs_again_when_it_is_requested_again() {
    let app = spawn_app().await;
    let body = json!({"function": "sin(13*x)*cos(17*y)", "max_vertices": 400_000});
    let status: Value = app.post("/v1/jobs", &body).await.json().await.unwrap();
    let id = status["id"].as_str().unwrap().to_owned();
    app.wait_running(&id).await;
    let cancelled: Value = app.delete(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    assert_eq!(cancelled["status"], "cancelled");
    let again = app.post("/v1/jobs", &body).await;
    assert_eq!(again.status(), 202, "a cancelled job is not the answer: it runs again");
    assert_eq!(app.wait_finished(&id).await["status"], "succeeded");
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 2.0);
    app.shutdown().await;
}

#[tokio::test]
async fn finished_jobs_keep_their_status_but_not_their_mesh_outside_the_cache() {
    let mut config = crate::helpers::test_config();
    config.cache.memory_bytes = 0;
    let app = crate::helpers::spawn_with(config).await;
    let status: Value =
        app.post("/v1/jobs", &json!({"function": "x*y", "max_vertices": 1000})).await.json().await.unwrap();
    let id = status["id"].as_str().unwrap();
    let done = app.wait_finished(id).await;
    assert_eq!(done["status"], "succeeded");
    assert_eq!(done["stats"]["vertices"], 1000);
    let mesh = app.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(mesh.status(), 404);
    let problem: Value = mesh.json().await.unwrap();
    assert!(problem["detail"].as_str().unwrap().contains("no longer cached"), "{problem}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_queue_of_zero_still_runs_jobs_on_idle_workers() {
    let mut config = crate::helpers::test_config();
    config.pool.queue = 0;
    let app = crate::helpers::spawn_with(config).await;
    assert_eq!(app.get("/readyz").await.status(), 200);
    let response = app.post("/v1/meshes", &json!({"function": "x", "max_vertices": 10})).await;
    assert_eq!(response.status(), 200);
    app.shutdown().await;
}

/// The smallest angle of each triangle of a mesh document, in degrees.
fn smallest_angles(doc: &Value) -> Vec<f64> {
    let v = |i: &Value| {
        let p = &doc["vertices"][i.as_u64().unwrap() as usize];
        (p[0].as_f64().unwrap(), p[1].as_f64().unwrap())
    };
    let angle = |p: (f64, f64), q: (f64, f64), r: (f64, f64)| {
        let (u, w) = ((q.0 - p.0, q.1 - p.1), (r.0 - p.0, r.1 - p.1));
        (u.0 * w.1 - u.1 * w.0).abs().atan2(u.0 * w.0 + u.1 * w.1).to_degrees()
    };
    let triangles = doc["triangles"].as_array().unwrap();
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = [v(&t[0]), v(&t[1]), v(&t[2])];
            angle(a, b, c).min(angle(b, c, a)).min(angle(c, a, b))
        })
        .collect()
}

#[tokio::test]
async fn no_needles_by_default_and_min_angle_bounds_every_angle_it_could_repair() {
    let app = spawn_app().await;
    // F vanishes along y = 0, where the vertices above a side once crowded into needles.
    let base = json!({"function": "sin(5*x)*y", "domain": {"x": [0, 2], "y": [0, 1]}, "max_vertices": 5000});
    let doc: Value = app.post("/v1/meshes", &base).await.json().await.unwrap();
    let smallest = smallest_angles(&doc).into_iter().fold(f64::INFINITY, f64::min);
    assert!(smallest > 5.0, "smallest angle {smallest}°");
    assert!(doc["stats"].get("below_min_angle").is_none());
    let mut asked = base.clone();
    asked["min_angle"] = json!(25);
    let bounded: Value = app.post("/v1/meshes", &asked).await.json().await.unwrap();
    assert_ne!(bounded["id"], doc["id"], "min_angle is part of the id");
    let below = smallest_angles(&bounded).iter().filter(|&&a| a < 25.0).count();
    assert_eq!(bounded["stats"]["below_min_angle"], below, "the stats count what the mesh has");
    // Repairs go first: only the last step's triangles can be left, and none a floor stopped.
    assert!(below <= 4, "{below} triangles below 25°");
    assert_eq!(bounded["stats"]["vertices"], 5000);
    app.shutdown().await;
}

#[tokio::test]
async fn data_dependent_lowers_a_grid_meshs_worst_error_and_a_smaller_budget_runs_afresh() {
    let app = spawn_app().await;
    // A sharp peak and a ridge on 61 × 45 nodes, whose greedy run leaves one worst triangle.
    let (nx, ny) = (61, 45);
    let values: Vec<f64> = (0..nx * ny)
        .map(|k| {
            let (x, y) = ((k % nx) as f64, (k / nx) as f64);
            100.0 * (-((x - 17.0).powi(2) + (y - 29.0).powi(2)) / 8.0).exp() + 0.3 * (x - 2.0 * y).abs()
        })
        .collect();
    let request = |method: &str, n: u64| json!({"grid": {"nx": nx, "ny": ny, "values": values}, "max_vertices": n, "method": method});
    let delaunay: Value = app.post("/v1/meshes", &request("semi-recursive", 200)).await.json().await.unwrap();
    let flipped: Value = app.post("/v1/meshes", &request("data-dependent", 200)).await.json().await.unwrap();
    assert_ne!(flipped["id"], delaunay["id"], "the method is part of the id");
    assert_eq!(flipped["vertices"], delaunay["vertices"], "flips move no vertex");
    let worst = |doc: &Value| doc["stats"]["max_triangle_error"].as_f64().unwrap();
    assert!(worst(&flipped) < 0.6 * worst(&delaunay), "{} vs {}", worst(&flipped), worst(&delaunay));
    assert_eq!(
        (delaunay["stats"]["delaunay"].as_bool(), flipped["stats"]["delaunay"].as_bool()),
        (Some(true), Some(false))
    );
    // Its last flips depend on where it stops: a smaller budget is a run of its own, not a
    // replay of the larger one's steps, and gives what a fresh server gives.
    let smaller = app.post("/v1/meshes", &request("data-dependent", 150)).await;
    assert_eq!(smaller.headers()["x-cache"], "miss");
    let smaller = smaller.bytes().await.unwrap();
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 3.0);
    let fresh = spawn_app().await;
    assert_eq!(
        fresh.post("/v1/meshes", &request("data-dependent", 150)).await.bytes().await.unwrap(),
        smaller
    );
    fresh.shutdown().await;
    app.shutdown().await;
}

#[tokio::test]
async fn the_error_criterion_is_the_default_and_reports_its_max_triangle_error() {
    let app = spawn_app().await;
    let bump = "exp(-100*((x-0.4)^2+(y-0.6)^2))";
    let client = &app;
    let post =
        |body: Value| async move { client.post("/v1/meshes", &body).await.json::<Value>().await.unwrap() };
    let doc = post(json!({"function": bump, "max_vertices": 2000})).await;
    assert_eq!(doc["stats"]["vertices"], 2000);
    let worst = doc["stats"]["max_triangle_error"].as_f64().unwrap();
    assert!(worst > 0.0 && worst < 0.01, "{worst}");
    let explicit = post(json!({"function": bump, "max_vertices": 2000, "criterion": "error"})).await;
    assert_eq!(doc["id"], explicit["id"], "the default is the error criterion");
    let paper = post(json!({"function": bump, "max_vertices": 2000, "criterion": "variation"})).await;
    assert_ne!(doc["id"], paper["id"], "the criterion is part of the id");
    assert!(paper["stats"].get("max_triangle_error").is_none());
    app.shutdown().await;
}

#[tokio::test]
async fn the_job_list_pages_newest_first_filters_by_status_and_refuses_a_bad_query() {
    let app = spawn_app().await;
    let mut ids = Vec::new();
    for k in 0..5 {
        let body = json!({"function": format!("x*y + {k}"), "max_vertices": 50});
        let status: Value = app.post("/v1/jobs", &body).await.json().await.unwrap();
        ids.push(status["id"].as_str().unwrap().to_owned());
        app.wait_finished(ids.last().unwrap()).await;
    }
    // A cancelled one, newest of all.
    let long = json!({"function": "sin(40*x*y)", "max_vertices": 2_000_000});
    let cancelled: Value = app.post("/v1/jobs", &long).await.json().await.unwrap();
    let cancelled = cancelled["id"].as_str().unwrap().to_owned();
    app.delete(&format!("/v1/jobs/{cancelled}")).await;
    app.wait_finished(&cancelled).await;

    let page = |path: String| {
        let app = &app;
        async move {
            let response = app.get(&path).await;
            assert_eq!(response.status(), 200, "{path}");
            response.json::<Value>().await.unwrap()
        }
    };
    let listed = |doc: &Value| -> Vec<String> {
        doc["jobs"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap().to_owned()).collect()
    };
    let all = page("/v1/jobs".into()).await;
    let newest_first: Vec<String> =
        std::iter::once(cancelled.clone()).chain(ids.iter().rev().cloned()).collect();
    assert_eq!(listed(&all), newest_first);
    assert!(all["next"].is_null());
    assert!(all["jobs"].as_array().unwrap().iter().all(|j| j["created_at"].is_string()), "{all}");
    // Two at a time, by the cursor each page gives.
    let mut seen = Vec::new();
    let mut next = Some("/v1/jobs?limit=2&status=succeeded".to_owned());
    while let Some(path) = next {
        let doc = page(path).await;
        let ids = listed(&doc);
        assert!(ids.len() <= 2);
        seen.extend(ids);
        next = doc["next"].as_str().map(str::to_owned);
    }
    assert_eq!(seen, ids.iter().rev().cloned().collect::<Vec<_>>(), "the succeeded, each once");
    assert_eq!(listed(&page("/v1/jobs?status=cancelled".into()).await), [cancelled]);
    for query in ["status=done", "limit=0", "limit=101", "cursor=abc", "colour=red"] {
        let response = app.get(&format!("/v1/jobs?{query}")).await;
        assert_eq!(response.status(), 422, "{query}");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn a_problem_with_nothing_to_solve_and_a_zero_time_limit_are_refused_naming_the_field() {
    let app = spawn_app().await;
    for (path, body, field) in [
        ("/v1/solutions", json!({}), "f"),
        (
            "/v1/solutions",
            json!({"physics": "magnetostatic", "regions": [{"x": [0, 0.5], "y": [0, 0.5], "mu_r": 1000}]}),
            "regions",
        ),
        ("/v1/solutions", json!({"f": 1, "time_limit_ms": 0}), "time_limit_ms"),
        ("/v1/meshes", json!({"function": "x*y", "time_limit_ms": 0}), "time_limit_ms"),
    ] {
        let response = app.post(path, &body).await;
        assert_eq!(response.status(), 422, "{body}");
        let doc: Value = response.json().await.unwrap();
        let named = doc.to_string();
        assert!(
            named.contains(&format!("\"{field}\"")) || doc["detail"].as_str().unwrap().starts_with(field),
            "{doc}"
        );
    }
    app.shutdown().await;
}
