//! Results as data: the format a client asks for, the same bytes for the same request, and
//! runs a time limit stopped kept apart from the answers.

use crate::helpers::{read_events, spawn_app};
use reqwest::StatusCode;
use serde_json::{Value, json};

fn body() -> Value {
    json!({"function": "exp(-3*((x-0.4)^2+(y-0.7)^2))", "max_vertices": 800})
}

#[tokio::test]
async fn an_unknown_format_is_406_listing_the_known_ones_before_any_work() {
    let app = spawn_app().await;
    let response = app.post("/v1/meshes?format=dxf", &body()).await;
    assert_eq!(response.status(), 406);
    assert_eq!(response.headers()["content-type"], "application/problem+json");
    let problem: Value = response.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/not-acceptable");
    assert!(problem["formats"].as_array().unwrap().contains(&json!("json")));
    assert!(problem["detail"].as_str().unwrap().contains("dxf"));
    let accept = app.client.post(app.url("/v1/meshes")).header("accept", "text/csv").json(&body());
    assert_eq!(accept.send().await.unwrap().status(), 406);
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 0.0, "refused before running");
    app.shutdown().await;
}

#[tokio::test]
async fn the_format_parameter_wins_over_accept_and_each_form_has_its_own_etag() {
    let app = spawn_app().await;
    let plain = app.post("/v1/meshes", &body()).await;
    let tag = plain.headers()["etag"].to_str().unwrap().to_owned();
    assert_eq!(plain.headers()["vary"], "accept");
    let request = app.client.post(app.url("/v1/meshes?format=obj&z_scale=3")).header("accept", "image/png");
    let scaled = request.json(&body()).send().await.unwrap();
    assert_eq!(scaled.headers()["content-type"], "model/obj");
    assert_eq!(scaled.headers()["x-cache"], "hit");
    assert_ne!(scaled.headers()["etag"].to_str().unwrap(), tag, "other options, other tag");
    app.shutdown().await;
}

/// The z of each `v x y z` line of an OBJ.
fn obj_heights(text: &str) -> Vec<f64> {
    text.lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| l.split(' ').nth(2).unwrap().parse().unwrap())
        .collect()
}

#[tokio::test]
async fn z_scale_stretches_every_3d_format_and_an_option_a_format_does_not_take_is_refused() {
    let app = spawn_app().await;
    let plain = app.post("/v1/meshes?format=obj", &body()).await.text().await.unwrap();
    let tall = app.post("/v1/meshes?format=obj&z_scale=2.5", &body()).await.text().await.unwrap();
    let (plain, tall) = (obj_heights(&plain), obj_heights(&tall));
    assert!(plain.iter().any(|&z| z != 0.0));
    assert_eq!(tall, plain.iter().map(|z| z * 2.5).collect::<Vec<_>>());
    for (query, option) in [
        ("format=json&z_scale=2", "z_scale"),
        ("format=png&z_scale=2", "z_scale"),
        ("format=svg&size=64", "size"),
        ("format=obj&size=64", "size"),
    ] {
        let response = app.post(&format!("/v1/meshes?{query}"), &body()).await;
        assert_eq!(response.status(), StatusCode::UNPROCESSABLE_ENTITY, "{query}");
        let doc: Value = response.json().await.unwrap();
        let detail = doc["detail"].as_str().unwrap();
        assert!(detail.starts_with(&format!("{option} does not apply to format")), "{query}: {detail}");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn two_servers_give_the_same_bytes_and_tag_and_the_time_goes_in_a_header() {
    let (a, b) = (spawn_app().await, spawn_app().await);
    let (ra, rb) = (a.post("/v1/meshes", &body()).await, b.post("/v1/meshes", &body()).await);
    assert_eq!(ra.headers()["etag"], rb.headers()["etag"]);
    let timing = ra.headers()["server-timing"].to_str().unwrap().to_owned();
    assert!(timing.starts_with("engine;dur="), "{timing}");
    let (ba, bb) = (ra.bytes().await.unwrap(), rb.bytes().await.unwrap());
    assert_eq!(ba, bb, "a recomputation is byte-identical");
    let doc: Value = serde_json::from_slice(&ba).unwrap();
    assert!(doc["stats"].get("elapsed_ms").is_none());
    let status: Value =
        a.get(&format!("/v1/jobs/{}", doc["id"].as_str().unwrap())).await.json().await.unwrap();
    assert!(status["elapsed_ms"].as_f64().unwrap() > 0.0, "the job record keeps the time: {status}");
    a.shutdown().await;
    b.shutdown().await;
}

#[tokio::test]
async fn a_run_its_time_limit_stopped_is_served_to_its_job_but_never_cached() {
    let app = spawn_app().await;
    let body = json!({"function": "sin(9*x)*cos(7*y)", "max_vertices": 2_000_000, "time_limit_ms": 1});
    let first = app.post("/v1/meshes", &body).await;
    assert_eq!(first.status(), 200);
    assert_eq!(first.headers()["x-cache"], "partial");
    assert!(first.headers().get("etag").is_none(), "its bytes depend on the machine");
    let doc: Value = first.json().await.unwrap();
    assert_eq!(doc["stats"]["stop"], "time_limit");
    let id = doc["id"].as_str().unwrap().to_owned();
    let mesh = app.get(&format!("/v1/jobs/{id}/mesh")).await;
    assert_eq!(mesh.headers()["x-cache"], "partial");
    let again: Value = mesh.json().await.unwrap();
    assert_eq!(again["vertices"], doc["vertices"], "the job's own result, not a new run");
    let second = app.post("/v1/meshes", &body).await;
    assert_eq!(second.headers()["x-cache"], "partial");
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 2.0, "not answered from the first run");
    app.shutdown().await;
}

#[tokio::test]
async fn the_result_event_carries_the_same_document_as_the_mesh_route() {
    let app = spawn_app().await;
    let created: Value = app.post("/v1/jobs", &body()).await.json().await.unwrap();
    let id = created["id"].as_str().unwrap().to_owned();
    app.wait_finished(&id).await;
    let mesh = app.get(&format!("/v1/jobs/{id}/mesh")).await.text().await.unwrap();
    let events = read_events(app.get(&format!("/v1/jobs/{id}/events?inline=mesh")).await).await;
    assert_eq!(events.len(), 1);
    assert_eq!((events[0].event.as_str(), events[0].data.as_str()), ("result", mesh.as_str()));
    app.shutdown().await;
}

#[tokio::test]
async fn evaluate_answers_the_surrogate_at_points_as_json_or_binary() {
    let app = spawn_app().await;
    let doc: Value = app.post("/v1/meshes", &body()).await.json().await.unwrap();
    let id = doc["id"].as_str().unwrap();
    let v = &doc["vertices"][17];
    let (x, y, z) = (v[0].as_f64().unwrap(), v[1].as_f64().unwrap(), v[2].as_f64().unwrap());
    let points = json!({"points": [[x, y], [2.0, 0.5], [0.0, 0.0]]});
    let answer: Value = app.post(&format!("/v1/jobs/{id}/evaluate"), &points).await.json().await.unwrap();
    let corner = doc["vertices"][0][2].as_f64().unwrap();
    assert_eq!(answer, json!({"values": [z, null, corner]}));
    let binary: Vec<u8> = [x, y, -1.0, 0.5].iter().flat_map(|c| c.to_le_bytes()).collect();
    let response = app
        .client
        .post(app.url(&format!("/v1/jobs/{id}/evaluate")))
        .header("content-type", "application/octet-stream")
        .body(binary)
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()["content-type"], "application/octet-stream");
    let bytes = response.bytes().await.unwrap();
    let values: Vec<f64> = bytes.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    assert_eq!(values.len(), 2);
    assert_eq!(values[0], z);
    assert!(values[1].is_nan(), "outside is NaN in binary");
    let odd = app
        .client
        .post(app.url(&format!("/v1/jobs/{id}/evaluate")))
        .header("content-type", "application/octet-stream");
    assert_eq!(odd.body(vec![0u8; 12]).send().await.unwrap().status(), 422);
    let unknown = app.post(&format!("/v1/jobs/{}/evaluate", "0".repeat(64)), &points).await;
    assert_eq!(unknown.status(), 404);
    app.shutdown().await;
}

#[tokio::test]
async fn smaller_budgets_and_passed_tolerances_are_replayed_byte_for_byte_without_running_f() {
    let app = spawn_app().await;
    // More nodes than the runs' vertices: on a grid's nodes, a run that matched them all would
    // answer every larger budget too.
    let grid: Vec<f64> =
        (0..80 * 60).map(|k| ((k % 80) as f64 * 0.4).sin() + ((k / 80) as f64 * 0.3).cos()).collect();
    // With `quality` the replay measures its mesh against F as a fresh run does.
    let sources = [
        json!({"function": "sin(6*x)*cos(4*y)"}),
        json!({"grid": {"nx": 80, "ny": 60, "values": grid}}),
        json!({"function": "sin(6*x)*cos(4*y)", "quality": true}),
    ];
    let mut runs = 0.0;
    for source in sources {
        for method in ["semi-recursive", "recursive"] {
            for criterion in ["error", "variation"] {
                let with = |extra: Value| {
                    let mut body = source.clone();
                    body["method"] = json!(method);
                    body["criterion"] = json!(criterion);
                    body.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
                    body
                };
                let big: Value =
                    app.post("/v1/meshes", &with(json!({"max_vertices": 3000}))).await.json().await.unwrap();
                runs += 1.0;
                // A tolerance the big run passed, and a smaller budget.
                let passed = big["stats"]["variation"].as_f64().unwrap() * 4.0;
                for extra in
                    [json!({"max_vertices": 1234}), json!({"max_vertices": 3000, "tolerance": passed})]
                {
                    let body = with(extra);
                    let replayed = app.post("/v1/meshes", &body).await;
                    assert_eq!(replayed.headers()["x-cache"], "prefix", "{body}");
                    let tag = replayed.headers()["etag"].clone();
                    let bytes = replayed.bytes().await.unwrap();
                    // A server that has seen nothing else computes it.
                    let fresh = spawn_app().await;
                    let computed = fresh.post("/v1/meshes", &body).await;
                    assert_eq!(computed.headers()["x-cache"], "miss");
                    assert_eq!(computed.headers()["etag"], tag);
                    assert_eq!(computed.bytes().await.unwrap(), bytes, "{body}");
                    fresh.shutdown().await;
                    // Stored under its own id: the next time it is a plain hit.
                    assert_eq!(app.post("/v1/meshes", &body).await.headers()["x-cache"], "hit");
                }
                assert_eq!(
                    app.metric("meshfit_engine_runs_total").await,
                    runs,
                    "F ran only for the big runs"
                );
                let larger = app.post("/v1/meshes", &with(json!({"max_vertices": 3001}))).await;
                assert_eq!(larger.headers()["x-cache"], "miss", "a larger budget runs fresh");
                runs += 1.0;
            }
        }
    }
    assert_eq!(app.metric("meshfit_prefix_hits_total").await, 24.0);
    app.shutdown().await;
}

#[tokio::test]
async fn every_format_comes_back_from_the_mesh_route_with_its_media_type_and_signature() {
    let app = spawn_app().await;
    let doc: Value = app.post("/v1/meshes", &body()).await.json().await.unwrap();
    let (id, triangles) = (doc["id"].as_str().unwrap(), doc["triangles"].as_array().unwrap().len());
    let starts: [(&str, &str, &[u8]); 8] = [
        ("obj", "model/obj", b"# meshfit"),
        ("ply", "application/x-ply", b"ply\nformat binary_little_endian 1.0"),
        ("stl", "model/stl", b""),
        ("vtu", "application/vnd.vtk.vtu+xml", b"<?xml"),
        ("msh", "text/x-gmsh", b"$MeshFormat\n4.1 0 8"),
        ("glb", "model/gltf-binary", b"glTF"),
        ("svg", "image/svg+xml", b"<?xml"),
        ("png", "image/png", b"\x89PNG\r\n\x1a\n"),
    ];
    for (name, media, start) in starts {
        let response = app.get(&format!("/v1/jobs/{id}/mesh?format={name}")).await;
        assert_eq!(response.status(), 200, "{name}");
        assert_eq!(response.headers()["content-type"], media, "{name}");
        assert_eq!(response.headers()["etag"].to_str().unwrap(), format!("\"{id}.{name}\""));
        let bytes = response.bytes().await.unwrap();
        assert!(bytes.starts_with(start), "{name}: {:?}", &bytes[..16.min(bytes.len())]);
        if name == "stl" {
            // 80-byte header, the facet count, 50 bytes a facet.
            assert_eq!(u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize, triangles);
            assert_eq!(bytes.len(), 84 + 50 * triangles);
        }
        // The same bytes by media type.
        let by_accept = app.client.get(app.url(&format!("/v1/jobs/{id}/mesh"))).header("accept", media);
        assert_eq!(by_accept.send().await.unwrap().bytes().await.unwrap(), bytes, "{name} by Accept");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn quality_is_measured_only_when_asked_and_agrees_with_the_criterions_own_maximum() {
    let app = spawn_app().await;
    let body = json!({"function": "sin(6*x)*cos(4*y)", "max_vertices": 2000});
    let plain: Value = app.post("/v1/meshes", &body).await.json().await.unwrap();
    assert!(plain["stats"].get("quality").is_none(), "not asked, not measured");
    let mut asked = body.clone();
    asked["quality"] = json!(true);
    let measured: Value = app.post("/v1/meshes", &asked).await.json().await.unwrap();
    assert_ne!(plain["id"], measured["id"], "quality is part of the request");
    assert_eq!(plain["vertices"], measured["vertices"], "and changes nothing of the mesh");
    let (stats, quality) = (&measured["stats"], &measured["stats"]["quality"]);
    // The error criterion samples the same lattice, so its final maximum is the E_n estimate.
    assert_eq!(quality["max_error"], stats["max_triangle_error"]);
    let (max, rms) = (quality["max_error"].as_f64().unwrap(), quality["rms_error"].as_f64().unwrap());
    assert!(0.0 < rms && rms < max, "rms {rms}, max {max}");
    let angle = quality["min_angle_deg"].as_f64().unwrap();
    assert!(0.0 < angle && angle <= 60.0, "{angle}");
    // 12 samples a triangle, minus none: F is finite everywhere.
    assert_eq!(quality["samples"], 12 * stats["triangles"].as_u64().unwrap());
    app.shutdown().await;
}
