//! Replicas sharing through Redis: real `redis-server` and meshfit processes on loopback
//! ports, spoken to over HTTP. Skipped when `redis-server` is not installed, unless
//! `REDIS_TESTS=required` (as in CI).

mod harness;

use harness::{Redis, Replica, events, redis_available};
use serde_json::{Value, json};

const ENGINE_RUNS: &str = "meshfit_engine_runs_total";

/// A job that runs for seconds: long enough to act on it while it runs.
fn long(vertices: u64) -> Value {
    json!({"function": "sin(40*x)*cos(40*y)", "criterion": "variation", "max_vertices": vertices})
}

/// Redis and two replicas with `settings`, or `None` (the test is skipped) without
/// `redis-server`.
async fn pair(settings: &[(&str, &str)]) -> Option<(Redis, Replica, Replica)> {
    if !redis_available() {
        return None;
    }
    let redis = Redis::start().await;
    let a = Replica::start_with("a", &redis, settings).await;
    let b = Replica::start_with("b", &redis, settings).await;
    Some((redis, a, b))
}

async fn submit(replica: &Replica, body: &Value) -> String {
    let response = replica.post("/v1/jobs", body).await;
    assert_eq!(response.status(), 202, "a new job is accepted");
    let status: Value = response.json().await.unwrap();
    status["id"].as_str().unwrap().to_owned()
}

async fn mesh(replica: &Replica, id: &str) -> (String, bytes::Bytes) {
    let response = replica.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(response.status(), 200, "the mesh is served on {}", replica.addr);
    let etag = response.headers()["etag"].to_str().unwrap().to_owned();
    (etag, response.bytes().await.unwrap())
}

#[tokio::test]
async fn a_job_submitted_on_one_replica_is_followed_and_fetched_on_another() {
    let Some((redis, a, b)) = pair(&[]).await else { return };
    let id = submit(&a, &json!({"function": "exp(-9*(x*x+y*y))", "max_vertices": 60_000})).await;
    // B has never seen the request: it follows the job through Redis to its final event.
    let response = b.get(&format!("/v1/jobs/{id}/events?inline=mesh")).await;
    assert_eq!(response.status(), 200);
    let stream = events(response).await;
    let (last_event, last_data) = stream.last().expect("a final event");
    assert_eq!(last_event, "result");
    let streamed: Value = serde_json::from_str(last_data).unwrap();
    assert_eq!(streamed["id"], id.as_str());

    let (tag_a, bytes_a) = mesh(&a, &id).await;
    let (tag_b, bytes_b) = mesh(&b, &id).await;
    assert_eq!((tag_a, bytes_a.len()), (tag_b, bytes_b.len()));
    assert!(bytes_a == bytes_b, "the same bytes from either replica");
    assert_eq!(serde_json::from_slice::<Value>(&bytes_b).unwrap(), streamed, "the event is the mesh");
    assert_eq!(b.status(&id).await["status"], "succeeded");
    assert_eq!((a.metric(ENGINE_RUNS).await, b.metric(ENGINE_RUNS).await), (1.0, 0.0));
    assert_eq!(b.metric("meshfit_shared_hits_total").await, 1.0, "B read the result from Redis once");

    // A third replica asked by many clients at once reads the result from Redis once too.
    let c = Replica::start("c", &redis).await;
    let path = format!("/v1/jobs/{id}/mesh");
    let asks = (0..8).map(|_| c.client.get(c.url(&path)).send());
    for response in futures_util::future::join_all(asks).await {
        let response = response.unwrap();
        assert_eq!(response.status(), 200);
        assert!(response.bytes().await.unwrap() == bytes_a);
    }
    assert_eq!(c.metric("meshfit_shared_hits_total").await, 1.0, "one read for eight clients");
    assert_eq!(c.metric(ENGINE_RUNS).await, 0.0);
}

#[tokio::test]
async fn identical_requests_on_two_replicas_run_once() {
    let Some((_redis, a, b)) = pair(&[]).await else { return };
    let body = json!({"function": "x*y + sin(7*x)", "max_vertices": 200_000});
    let (ra, rb) = tokio::join!(a.post("/v1/meshes", &body), b.post("/v1/meshes", &body));
    assert_eq!((ra.status().as_u16(), rb.status().as_u16()), (200, 200));
    let (ba, bb) = (ra.bytes().await.unwrap(), rb.bytes().await.unwrap());
    assert!(ba == bb, "both clients get the same mesh");
    let runs = a.metric(ENGINE_RUNS).await + b.metric(ENGINE_RUNS).await;
    assert_eq!(runs, 1.0, "one engine run between the two replicas");
    let followed =
        a.metric("meshfit_jobs_followed_total").await + b.metric("meshfit_jobs_followed_total").await;
    assert_eq!(followed, 1.0, "the other replica followed it");
}

#[tokio::test]
async fn a_job_whose_replica_is_killed_is_taken_over_and_its_follower_sees_it_finish() {
    let Some((_redis, mut a, b)) = pair(&[]).await else { return };
    let id = submit(&a, &long(1_000_000)).await;
    b.wait_status(&id, |s| s == "running").await;
    let stream = tokio::spawn({
        let request = b.client.get(b.url(&format!("/v1/jobs/{id}/events")));
        async move { events(request.send().await.unwrap()).await }
    });
    a.kill();
    let stream = stream.await.unwrap();
    let (last_event, last_data) = stream.last().expect("a final event");
    assert_eq!(last_event, "result", "the follower sees the job finish: {last_data:.300}");
    let result: Value = serde_json::from_str(last_data).unwrap();
    assert_eq!(result["stats"]["vertices"], 1_000_000);
    assert_eq!(b.metric("meshfit_takeovers_total").await, 1.0);
    assert_eq!(b.metric(ENGINE_RUNS).await, 1.0);
    let (_, bytes) = mesh(&b, &id).await;
    assert_eq!(serde_json::from_slice::<Value>(&bytes).unwrap()["stats"], result["stats"]);
}

/// An .npy grid file of `nx`·`ny` little-endian f64 heights, rows from the bottom.
fn npy(nx: usize, ny: usize, height: impl Fn(usize, usize) -> f64) -> Vec<u8> {
    let header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({ny}, {nx}), }}");
    let pad = 64 - (10 + header.len() + 1) % 64;
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&((header.len() + pad + 1) as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend(std::iter::repeat_n(b' ', pad));
    bytes.push(b'\n');
    bytes.extend(
        (0..ny).flat_map(|j| (0..nx).map(move |i| (i, j))).flat_map(|(i, j)| height(i, j).to_le_bytes()),
    );
    bytes
}

#[tokio::test]
async fn a_job_from_an_uploaded_grid_file_is_taken_over_from_its_kept_spec() {
    // The replica that takes over never sees the file: it runs the spec A kept, whose
    // decoded heights hash to the same id.
    let Some((redis, mut a, b)) = pair(&[]).await else { return };
    let (nx, ny) = (800, 600);
    let file = npy(nx, ny, |i, j| ((i as f64) * 0.05).sin() * ((j as f64) * 0.07).cos() * 100.0);
    let request = json!({"max_vertices": 400_000, "domain": {"x": [0, 800], "y": [0, 600]}});
    let form = reqwest::multipart::Form::new()
        .text("request", request.to_string())
        .part("grid", reqwest::multipart::Part::bytes(file).file_name("dem.npy"));
    let response = a.client.post(a.url("/v1/jobs")).multipart(form).send().await.unwrap();
    assert_eq!(response.status(), 202, "a new job is accepted");
    let id = response.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_owned();
    b.wait_status(&id, |s| s == "running").await;
    redis.wait_pending(&id).await;
    a.kill();
    let status = b.wait_status(&id, |s| !matches!(s, "queued" | "running")).await;
    assert_eq!(status["status"], "succeeded", "{status}");
    assert_eq!(status["stats"]["vertices"], 400_000);
    assert_eq!(b.metric("meshfit_takeovers_total").await, 1.0);
    assert_eq!(b.metric(ENGINE_RUNS).await, 1.0);
}

#[tokio::test]
async fn a_replica_shutting_down_hands_its_job_to_another_before_its_lease_expires() {
    // A lease longer than the client waits: only a job handed back is taken over in time.
    let Some((_redis, mut a, b)) = pair(&[("MESHFIT_REDIS_LEASE_MS", "600000")]).await else { return };
    let id = submit(&a, &long(1_000_000)).await;
    b.wait_status(&id, |s| s == "running").await;
    // Both streams are open (their heads answered) before A is told to stop.
    let open = async |replica: &Replica| {
        replica.client.get(replica.url(&format!("/v1/jobs/{id}/events"))).send().await.unwrap()
    };
    let (on_a, on_b) = (tokio::spawn(events(open(&a).await)), tokio::spawn(events(open(&b).await)));
    assert!(a.terminate(), "A shuts down cleanly");
    // A's own client is not told the job was cancelled: its stream ends without a final
    // event, so that it reconnects and follows the job on another replica.
    let on_a = on_a.await.unwrap();
    assert!(on_a.iter().all(|(event, _)| event == "progress"), "{:?}", on_a.last());
    let stream = on_b.await.unwrap();
    let (last_event, last_data) = stream.last().expect("a final event");
    assert_eq!(last_event, "result", "{last_data:.300}");
    assert_eq!(b.metric("meshfit_takeovers_total").await, 1.0);
    assert_eq!(b.status(&id).await["status"], "succeeded");
}

#[tokio::test]
async fn a_replica_stopping_with_no_client_connected_hands_its_job_back_once() {
    // No connection keeps A's server up, so its drain loop cancels the job past a short
    // grace, again every few milliseconds until the worker lets go: the job must still be
    // handed back, not cancelled. The lease outlasts the test: only a hand-back is taken over.
    let settings = [("MESHFIT_REDIS_LEASE_MS", "600000"), ("MESHFIT_SHUTDOWN_GRACE_MS", "1000")];
    let Some((_redis, mut a, b)) = pair(&settings).await else { return };
    let id = submit(&a, &long(1_000_000)).await;
    b.wait_status(&id, |s| s == "running").await;
    assert!(a.terminate(), "A shuts down cleanly");
    let status = b.wait_status(&id, |s| !matches!(s, "queued" | "running")).await;
    assert_eq!(status["status"], "succeeded", "{status}");
    assert_eq!(b.metric("meshfit_takeovers_total").await, 1.0);
    assert_eq!(b.metric(ENGINE_RUNS).await, 1.0);
}

#[tokio::test]
async fn delete_on_any_replica_cancels_the_job_where_it_runs_and_a_new_request_runs_it_again() {
    let Some((_redis, a, b)) = pair(&[]).await else { return };
    let body = long(1_000_000);
    let id = submit(&a, &body).await;
    b.wait_status(&id, |s| s == "running").await;
    let response = b.client.delete(b.url(&format!("/v1/jobs/{id}"))).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let status: Value = response.json().await.unwrap();
    assert_eq!(status["status"], "cancelled", "B answers once A has stopped: {status}");
    assert_eq!(a.status(&id).await["status"], "cancelled");
    assert_eq!(a.metric("meshfit_jobs_finished_total{state=\"cancelled\"}").await, 1.0);
    let response = b.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(response.status(), 409, "a cancelled job has no mesh");

    // The cancel was for that run: the same request runs again, to the end.
    let response = b.post("/v1/meshes", &body).await;
    assert_eq!(response.status(), 200, "{}", response.text().await.unwrap());
    assert_eq!(b.metric(ENGINE_RUNS).await, 1.0);
    // B answered its client as the run ended; A hears of it once B has stored the result.
    a.wait_status(&id, |s| s == "succeeded").await;
    assert!(mesh(&a, &id).await.1 == mesh(&b, &id).await.1);
}

#[tokio::test]
async fn replicas_keep_serving_while_redis_is_down_and_share_again_when_it_returns() {
    let Some((mut redis, a, b)) = pair(&[]).await else { return };
    a.wait_redis("up").await;
    let before = submit(&a, &json!({"function": "x+y*y", "max_vertices": 5_000})).await;
    a.wait_status(&before, |s| s == "succeeded").await;
    let (_, stored) = mesh(&a, &before).await;
    let running = submit(&a, &long(1_000_000)).await;
    b.wait_status(&running, |s| s == "running").await;

    // Redis goes away in the middle of A's run.
    redis.stop();
    for replica in [&a, &b] {
        replica.wait_redis("down").await;
        assert_eq!(replica.get("/readyz").await.status(), 200, "a replica without Redis still serves");
        assert_eq!(replica.metric("meshfit_redis_up").await, 0.0);
    }
    // A runs its job to the end; B, which cannot know, says to retry rather than "no such job".
    a.wait_status(&running, |s| s == "succeeded").await;
    let unknown = b.get(&format!("/v1/jobs/{running}")).await;
    assert_eq!(unknown.status(), 503);
    assert_eq!(unknown.json::<Value>().await.unwrap()["type"], "/problems/redis-unavailable");
    // What A had stored is still served, and new work is done alone.
    assert!(mesh(&a, &before).await.1 == stored, "nothing stored is lost");
    let alone = json!({"function": "cos(3*x)*y", "max_vertices": 5_000});
    let (ra, rb) = tokio::join!(a.post("/v1/meshes", &alone), b.post("/v1/meshes", &alone));
    assert_eq!((ra.status().as_u16(), rb.status().as_u16()), (200, 200));
    assert!(ra.bytes().await.unwrap() == rb.bytes().await.unwrap());

    redis.restart().await;
    for replica in [&a, &b] {
        replica.wait_redis("up").await;
        assert_eq!(replica.metric("meshfit_redis_up").await, 1.0);
    }
    // The job that ended during the outage is told to Redis once it is back (it restarted
    // empty): B serves it without running it.
    b.wait_status(&running, |s| s == "succeeded").await;
    assert!(mesh(&a, &running).await.1 == mesh(&b, &running).await.1);
    let after = submit(&a, &json!({"function": "x*x-y", "max_vertices": 5_000})).await;
    b.wait_status(&after, |s| s == "succeeded").await;
    assert!(mesh(&a, &after).await.1 == mesh(&b, &after).await.1, "shared again");
    assert_eq!(b.metric(ENGINE_RUNS).await, 1.0, "B ran only the job of the outage");
}

/// The quick start's DEM in EPSG:4326, as a multipart upload.
fn dem_upload() -> reqwest::multipart::Form {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/grids/dem-4326.tif");
    let part = reqwest::multipart::Part::bytes(std::fs::read(path).unwrap()).file_name("dem-4326.tif");
    reqwest::multipart::Form::new().part("grid", part)
}

#[tokio::test]
async fn a_dataset_uploaded_to_one_replica_is_served_and_deleted_by_another() {
    let Some((_redis, a, b)) = pair(&[]).await else { return };
    let created = a.client.post(a.url("/v1/datasets")).multipart(dem_upload()).send().await.unwrap();
    assert_eq!(created.status(), 201);
    let info: Value = created.json().await.unwrap();
    assert_eq!(info["shared"], true, "kept in Redis for the other replicas");
    let id = info["id"].as_str().unwrap().to_owned();
    // B was never sent the file: it reads it from Redis and describes it alike.
    let seen: Value = b.get(&format!("/v1/datasets/{id}")).await.json().await.unwrap();
    assert_eq!(
        (&seen["size"], &seen["max_zoom"], &seen["heights"]),
        (&info["size"], &info["max_zoom"], &info["heights"])
    );
    let layer = format!("/v1/tiles/{id}/layer.json");
    assert_eq!(a.get(&layer).await.bytes().await.unwrap(), b.get(&layer).await.bytes().await.unwrap());
    // A tile made on A is read by B from Redis, byte for byte, with the same tag.
    let path = format!("/v1/tiles/{id}/0/0/0.terrain?extensions=octvertexnormals-metadata");
    let tile = |r: &Replica| r.client.get(r.url(&path)).header("accept-encoding", "gzip").send();
    let made = tile(&a).await.unwrap();
    assert_eq!(made.headers()["x-cache"], "miss");
    let read = tile(&b).await.unwrap();
    assert_eq!(read.headers()["x-cache"], "shared");
    assert_eq!(read.headers()["etag"], made.headers()["etag"]);
    assert_eq!(read.bytes().await.unwrap(), made.bytes().await.unwrap());
    // Deleted on B, it is gone from A too (told by a message).
    let deleted = b.client.delete(b.url(&format!("/v1/datasets/{id}"))).send().await.unwrap();
    assert_eq!(deleted.status(), 204);
    let mut gone = false;
    for _ in 0..200 {
        if a.get(&format!("/v1/datasets/{id}")).await.status() == 404 {
            gone = true;
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    assert!(gone, "A still serves a dataset deleted on B");
    assert_eq!(b.get(&format!("/v1/datasets/{id}")).await.status(), 404);
}

#[tokio::test]
async fn a_dataset_larger_than_redis_keeps_is_served_by_its_replica_and_the_other_says_why_not() {
    let Some((_redis, a, b)) = pair(&[("MESHFIT_REDIS_MAX_BYTES", "50000")]).await else { return };
    let created = a.client.post(a.url("/v1/datasets")).multipart(dem_upload()).send().await.unwrap();
    assert_eq!(created.status(), 201);
    let info: Value = created.json().await.unwrap();
    assert_eq!(info["shared"], false, "93 KB is more than Redis keeps here");
    let id = info["id"].as_str().unwrap();
    assert_eq!(a.get(&format!("/v1/tiles/{id}/layer.json")).await.status(), 200);
    let missing = b.get(&format!("/v1/tiles/{id}/layer.json")).await;
    assert_eq!(missing.status(), 404);
    let problem: Value = missing.json().await.unwrap();
    assert!(problem["detail"].as_str().unwrap().contains("MESHFIT_REDIS_MAX_BYTES"), "{problem}");
}

/// `{"values": [...]}` telling F = x·y + sin(3x) at `points` as an `ask` answer lists them.
fn told(points: &Value) -> Value {
    let values: Vec<Value> = (points.as_array().unwrap().iter())
        .map(|p| {
            let (x, y) = (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap());
            json!({"id": p["id"], "value": x * y + (3.0 * x).sin()})
        })
        .collect();
    json!({"values": values})
}

/// Asks `replica` for job `id`'s next batch and tells it, `batches` times or until the job
/// ends: how many batches were told.
async fn play(replica: &Replica, id: &str, batches: usize) -> usize {
    let mut played = 0;
    while played < batches {
        let response = replica.get(&format!("/v1/jobs/{id}/ask?wait=9000")).await;
        if response.status() == 204 {
            continue;
        }
        assert_eq!(response.status(), 200, "{} answers for the job", replica.addr);
        let ask: Value = response.json().await.unwrap();
        if ask["status"] != "running" {
            break;
        }
        let response = replica.post(&format!("/v1/jobs/{id}/tell"), &told(&ask["points"])).await;
        assert_eq!(response.status(), 200);
        played += 1;
    }
    played
}

#[tokio::test]
async fn a_client_job_made_on_a_replica_that_dies_is_carried_on_by_another() {
    let Some((redis, mut a, b)) = pair(&[]).await else { return };
    let body = json!({"source": "client", "max_vertices": 300, "batch": 8});
    let id = submit(&a, &body).await;
    assert_eq!(play(&a, &id, 5).await, 5);
    let told_on_a = a.status(&id).await["evaluations"]["told"].clone();
    a.kill();

    // B never saw the job: it rebuilds it from the log in Redis, with nothing told lost.
    assert_eq!(b.status(&id).await["evaluations"]["told"], told_on_a);
    assert!(play(&b, &id, usize::MAX).await > 0);
    let done = b.wait_status(&id, |s| s != "running").await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["stats"]["vertices"], 300);

    // The same values played on another replica from the start make the same bytes.
    let c = Replica::start("c", &redis).await;
    let again = submit(&c, &body).await;
    play(&c, &again, usize::MAX).await;
    c.wait_status(&again, |s| s != "running").await;
    let mesh_of = |(_, bytes): (String, bytes::Bytes)| {
        let mut mesh: Value = serde_json::from_slice(&bytes).unwrap();
        mesh["id"].take();
        mesh
    };
    let (on_b, on_c) = (mesh_of(mesh(&b, &id).await), mesh_of(mesh(&c, &again).await));
    assert_eq!(on_b["stats"]["vertices"], 300);
    assert!(on_b == on_c, "the mesh depends on the values alone");
}
