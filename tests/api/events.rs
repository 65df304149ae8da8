//! Server-sent events: order, ids, the final event, reconnection.

use crate::helpers::{read_events, spawn_app};
use serde_json::{Value, json};

#[tokio::test]
async fn the_stream_sends_progress_with_a_rising_fraction_then_a_light_result_that_links_the_mesh() {
    let app = spawn_app().await;
    let body = json!({"function": "sin(9*x)*cos(7*y) + x", "max_vertices": 600_000});
    let response = app
        .client
        .post(app.url("/v1/meshes"))
        .header("accept", "text/event-stream")
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let events = read_events(response).await;
    let (last, progress) = events.split_last().expect("at least the result");
    assert_eq!(last.event, "result", "the stream ends with the result");
    assert!(!progress.is_empty(), "a 600k-vertex job reports progress");
    assert!(progress.iter().all(|e| e.event == "progress"), "only progress before the result");
    let ids: Vec<u64> = events.iter().map(|e| e.id.expect("every event has an id")).collect();
    // Every progress event the job published reached this client, which reads as they come:
    // 1, 2, 3, …; the result follows the last (or, if the job ended just as it published
    // one, the one before it).
    let (&result_id, progress_ids) = ids.split_last().unwrap();
    assert_eq!(progress_ids, (1..=progress_ids.len() as u64).collect::<Vec<_>>(), "{ids:?}");
    assert!((1..=2).contains(&(result_id - progress_ids.len() as u64)), "{ids:?}");
    let counts: Vec<(u64, u64)> = progress
        .iter()
        .map(|e| {
            let p: Value = serde_json::from_str(&e.data).unwrap();
            (p["vertices"].as_u64().unwrap(), p["triangles"].as_u64().unwrap())
        })
        .collect();
    assert!(counts.windows(2).all(|w| w[0].0 <= w[1].0 && w[0].1 <= w[1].1), "{counts:?}");
    // Each event names the job's targets, and how far it is, never less than before.
    let fractions: Vec<f64> = progress
        .iter()
        .map(|e| {
            let p: Value = serde_json::from_str(&e.data).unwrap();
            assert_eq!(p["target"]["max_vertices"], 600_000, "{p}");
            let f = p["fraction"].as_f64().unwrap();
            let by_vertices = p["vertices"].as_f64().unwrap() / 600_000.0;
            assert!((0.0..=1.0).contains(&f) && f >= by_vertices, "{p}");
            f
        })
        .collect();
    assert!(fractions.windows(2).all(|w| w[0] <= w[1]), "{fractions:?}");

    // The result names the job, its stats and where the mesh is, in every format; the mesh is
    // fetched once, from there.
    let result: Value = serde_json::from_str(&last.data).unwrap();
    // The bound: under 64 kB whatever the mesh (the stats' history is most of it).
    assert!(last.data.len() < 64 << 10, "a light event: {} bytes", last.data.len());
    assert!(!last.data.contains("\"vertices\":["), "no mesh in it");
    let id = result["id"].as_str().unwrap();
    assert_eq!(result["status"], "succeeded");
    assert_eq!(result["stats"]["vertices"], 600_000);
    assert_eq!(result["formats"]["obj"], format!("/v1/jobs/{id}/mesh?format=obj"));
    let stored: Value = app.get(result["formats"]["json"].as_str().unwrap()).await.json().await.unwrap();
    assert_eq!(stored["stats"], result["stats"]);
    app.shutdown().await;
}

#[tokio::test]
async fn asked_inline_the_result_event_is_the_mesh_document_and_a_stream_names_its_job() {
    let app = spawn_app().await;
    let body = json!({"function": "x*y + sin(3*x)", "max_vertices": 2000});
    let response = app
        .client
        .post(app.url("/v1/meshes?inline=mesh"))
        .header("accept", "text/event-stream")
        .json(&body)
        .send()
        .await
        .unwrap();
    let location = response.headers()["content-location"].to_str().unwrap().to_owned();
    let events = read_events(response).await;
    let result: Value = serde_json::from_str(&events.last().unwrap().data).unwrap();
    let id = result["id"].as_str().unwrap();
    assert_eq!(location, format!("/v1/jobs/{id}"));
    let stored: Value = app.get(&format!("/v1/jobs/{id}/mesh")).await.json().await.unwrap();
    assert_eq!(result, stored);
    // The events route takes it too; another value is refused.
    let events = read_events(app.get(&format!("/v1/jobs/{id}/events?inline=mesh")).await).await;
    assert_eq!(serde_json::from_str::<Value>(&events[0].data).unwrap(), stored);
    assert_eq!(app.get(&format!("/v1/jobs/{id}/events?inline=all")).await.status(), 422);
    // A POST stream takes `inline` alone: its vertices are the events route's.
    let request = app.client.post(app.url("/v1/meshes?vertices=true")).header("accept", "text/event-stream");
    assert_eq!(request.json(&body).send().await.unwrap().status(), 422);
    app.shutdown().await;
}

#[tokio::test]
async fn a_finished_job_sends_its_final_event_at_once_and_last_event_id_skips_it() {
    let app = spawn_app().await;
    let status: Value =
        app.post("/v1/jobs", &json!({"function": "x*y", "max_vertices": 100})).await.json().await.unwrap();
    let id = status["id"].as_str().unwrap();
    app.wait_finished(id).await;
    let events = read_events(app.get(&format!("/v1/jobs/{id}/events")).await).await;
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].event, "result");
    let seen = events[0].id.unwrap();
    let again = app
        .client
        .get(app.url(&format!("/v1/jobs/{id}/events")))
        .header("last-event-id", seen.to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(again.status(), 204, "nothing new after the final event: 204 stops an EventSource");
    app.shutdown().await;
}

#[tokio::test]
async fn a_reconnecting_client_is_not_sent_progress_it_has_seen() {
    let app = spawn_app().await;
    let status: Value = app
        .post("/v1/jobs", &json!({"function": "sin(21*x)*y", "max_vertices": 600_000}))
        .await
        .json()
        .await
        .unwrap();
    let id = status["id"].as_str().unwrap();
    app.wait_finished(id).await;
    // Progress ids of a finished job are all below the final id; resuming after id 1 sends
    // only the final event (the job's progress is history).
    let events = read_events(
        app.client
            .get(app.url(&format!("/v1/jobs/{id}/events")))
            .header("last-event-id", "1")
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(events.len(), 1);
    let final_id = events[0].id.unwrap();
    assert!(final_id > 2, "a 600k-vertex job reports progress more than once: {final_id}");
    // The final event's id is the job's own, whoever asks: a client that has it is done.
    let status = app
        .client
        .get(app.url(&format!("/v1/jobs/{id}/events")))
        .header("last-event-id", final_id.to_string())
        .send()
        .await
        .unwrap()
        .status();
    assert_eq!(status, 204);
    app.shutdown().await;
}

#[tokio::test]
async fn a_failing_job_streams_an_error_event_with_the_problem() {
    let app = spawn_app().await;
    let response = app
        .client
        .post(app.url("/v1/meshes"))
        .header("accept", "text/event-stream")
        .json(&json!({"function": "ln(x - 0.5)"}))
        .send()
        .await
        .unwrap();
    let events = read_events(response).await;
    let last = events.last().unwrap();
    assert_eq!(last.event, "error");
    let problem: Value = serde_json::from_str(&last.data).unwrap();
    assert_eq!(problem["type"], "/problems/non-finite-value");
    assert_eq!(problem["status"], 422);
    app.shutdown().await;
}

#[tokio::test]
async fn a_stream_whose_client_hangs_up_mid_way_cancels_its_job() {
    let app = spawn_app().await;
    let body = json!({"function": "sin(40*x)*cos(40*y)", "max_vertices": 2_000_000});
    let mut response = app
        .client
        .post(app.url("/v1/meshes"))
        .header("accept", "text/event-stream")
        .json(&body)
        .send()
        .await
        .unwrap();
    // Read until the first progress event, then hang up.
    let mut seen = Vec::new();
    while !String::from_utf8_lossy(&seen).contains("event: progress") {
        seen.extend_from_slice(&response.chunk().await.unwrap().expect("the stream goes on"));
    }
    drop(response);
    for _ in 0..1000 {
        if app.metric("meshfit_jobs_finished_total{state=\"cancelled\"}").await == 1.0 {
            assert_eq!(app.metric("meshfit_jobs_running").await, 0.0);
            // The server goes on serving.
            assert_eq!(app.get("/healthz").await.status(), 200);
            return app.shutdown().await;
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    panic!("the job ran on after its only client hung up");
}

#[tokio::test]
async fn with_vertices_progress_events_carry_each_new_vertex_once_in_insertion_order() {
    let app = spawn_app().await;
    let body =
        json!({"function": "sin(9*x)*cos(7*y) + x", "max_vertices": 600_000, "criterion": "variation"});
    let status: Value = app.post("/v1/jobs", &body).await.json().await.unwrap();
    let id = status["id"].as_str().unwrap();
    let stream = app.get(&format!("/v1/jobs/{id}/events?vertices=true&inline=mesh")).await;
    let events = read_events(stream).await;
    let (last, progress) = events.split_last().unwrap();
    assert_eq!(last.event, "result");
    assert!(progress.len() >= 2, "a 600k-vertex job reports progress more than once");
    let mut points: Vec<f64> = Vec::new();
    for event in progress {
        let p: Value = serde_json::from_str(&event.data).unwrap();
        // Each event starts where the last one ended and brings the mesh up to its count, or
        // 65,536 vertices nearer to it.
        assert_eq!(p["first_point"].as_u64().unwrap() as usize, points.len() / 3, "{}", &event.data[..80]);
        let new = p["points"].as_array().unwrap();
        points.extend(new.iter().map(|v| v.as_f64().unwrap()));
        let count = p["vertices"].as_u64().unwrap() as usize;
        assert!(new.len() / 3 == 1 << 16 || points.len() / 3 == count, "{} of {count}", points.len() / 3);
    }
    // What was streamed is a prefix of the final mesh's vertices, bit for bit.
    let result: Value = serde_json::from_str(&last.data).unwrap();
    let vertices = result["vertices"].as_array().unwrap();
    assert!(points.len() / 3 < vertices.len());
    for (k, xyz) in points.chunks(3).enumerate() {
        let v: Vec<f64> = vertices[k].as_array().unwrap().iter().map(|c| c.as_f64().unwrap()).collect();
        assert_eq!(xyz, &v[..], "vertex {k}");
    }
    // Without the parameter the events are as before: counts only. (A running job: a
    // finished one sends no progress to look at.)
    let other =
        json!({"function": "sin(9*x)*cos(7*y) - x", "max_vertices": 600_000, "criterion": "variation"});
    let status: Value = app.post("/v1/jobs", &other).await.json().await.unwrap();
    let plain =
        read_events(app.get(&format!("/v1/jobs/{}/events", status["id"].as_str().unwrap())).await).await;
    let progress: Vec<_> = plain.iter().filter(|e| e.event == "progress").collect();
    assert!(!progress.is_empty(), "a running job reports progress");
    assert!(progress.iter().all(|e| !e.data.contains("points")));
    let bad = app.get(&format!("/v1/jobs/{id}/events?vertices=yes")).await;
    assert_eq!(bad.status(), 422);
    app.shutdown().await;
}
