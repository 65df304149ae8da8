//! Health, metrics, the OpenAPI document, request ids and shutdown.

use crate::helpers::spawn_app;
use meshfit::http::ROUTES;
use serde_json::{Value, json};

#[tokio::test]
async fn openapi_yaml_parses_and_names_every_route_the_router_serves() {
    let app = spawn_app().await;
    let response = app.get("/openapi.yaml").await;
    assert_eq!(response.status(), 200);
    let doc: serde_yaml_ng::Value = serde_yaml_ng::from_str(&response.text().await.unwrap()).unwrap();
    assert_eq!(doc["openapi"].as_str(), Some("3.1.0"));
    for (method, path) in ROUTES {
        assert!(doc["paths"][*path][*method].is_mapping(), "openapi.yaml lacks {method} {path}");
    }
    let documented: usize = doc["paths"]
        .as_mapping()
        .unwrap()
        .values()
        .map(|p| p.as_mapping().unwrap().keys().filter(|k| k.as_str() != Some("parameters")).count())
        .sum();
    assert_eq!(documented, ROUTES.len(), "openapi.yaml documents a route the router lacks");
    // Every route in the list is really served (not the 404 fallback).
    for (method, path) in ROUTES {
        let path = path.replace("{id}", &"0".repeat(64));
        let response =
            app.client.request(method.to_uppercase().parse().unwrap(), app.url(&path)).send().await.unwrap();
        let problem: Option<Value> = response.json().await.ok();
        let no_route =
            problem.is_some_and(|p| p["detail"].as_str().is_some_and(|d| d.starts_with("no such route")));
        assert!(!no_route, "{method} {path} is not routed");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn metrics_report_jobs_cache_and_request_latency() {
    let app = spawn_app().await;
    app.post("/v1/meshes", &json!({"function": "x", "max_vertices": 10})).await;
    app.post("/v1/meshes", &json!({"function": "x", "max_vertices": 10})).await;
    let text = app.get("/metrics").await.text().await.unwrap();
    for name in [
        "meshfit_jobs_queued",
        "meshfit_jobs_running",
        "meshfit_jobs_finished_total{state=\"succeeded\"} 1",
        "meshfit_engine_runs_total 1",
        "meshfit_cache_hits_total 1",
        "meshfit_cache_misses_total 1",
        "meshfit_cache_bytes",
        "meshfit_http_request_duration_seconds_bucket",
        "meshfit_http_requests_total{method=\"POST\",status=\"200\"} 2",
    ] {
        assert!(text.contains(name), "/metrics lacks {name}:\n{text}");
    }
    assert!(app.metric("meshfit_cache_bytes").await > 0.0);
    // Any token is a method; the label set stays fixed.
    app.client.request("FROB".parse().unwrap(), app.url("/healthz")).send().await.unwrap();
    let text = app.get("/metrics").await.text().await.unwrap();
    assert!(text.contains("method=\"OTHER\""), "{text}");
    assert!(!text.contains("FROB"));
    app.shutdown().await;
}

#[tokio::test]
async fn every_response_carries_a_request_id() {
    let app = spawn_app().await;
    let ok = app.get("/healthz").await;
    let not_found = app.get("/nope").await;
    for response in [ok, not_found] {
        let id = response.headers()["x-request-id"].to_str().unwrap();
        assert_eq!(id.len(), 36, "a UUID: {id}");
    }
    let given = app.client.get(app.url("/healthz")).header("x-request-id", "abc-123").send().await.unwrap();
    assert_eq!(given.headers()["x-request-id"], "abc-123");
    // Ids too long or with characters a log line would need to quote are replaced, not echoed.
    for unsafe_id in ["a".repeat(10_000), "x level=error msg=forged".into()] {
        let replaced =
            app.client.get(app.url("/healthz")).header("x-request-id", &unsafe_id).send().await.unwrap();
        let id = replaced.headers()["x-request-id"].to_str().unwrap();
        assert_eq!(id.len(), 36, "a fresh UUID: {id}");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn oversized_targets_and_headers_are_problems_with_a_request_id() {
    let app = spawn_app().await;
    let long_target = app.get(&format!("/v1/jobs/{}", "a".repeat(9_000))).await;
    let many_headers = (0..40)
        .fold(app.client.get(app.url("/healthz")), |r, i| r.header(format!("x-h{i}"), "v".repeat(1_000)));
    let many_headers = many_headers.send().await.unwrap();
    for (response, status) in [(long_target, 414), (many_headers, 431)] {
        assert_eq!(response.status(), status);
        assert!(response.headers().contains_key("x-request-id"));
        assert_eq!(response.headers()["content-type"], "application/problem+json");
        let problem: Value = response.json().await.unwrap();
        assert_eq!(problem["type"], "/problems/limit-exceeded");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn shutdown_cancels_a_detached_job_after_the_grace_period_and_returns() {
    let mut config = crate::helpers::test_config();
    config.shutdown_grace = std::time::Duration::from_millis(200);
    let app = crate::helpers::spawn_with(config).await;
    let status: Value = app
        .post("/v1/jobs", &json!({"function": "sin(50*x)*cos(50*y)", "max_vertices": 2_000_000}))
        .await
        .json()
        .await
        .unwrap();
    let id = status["id"].as_str().unwrap().to_owned();
    app.wait_running(&id).await;
    // A client following the job hears how it ended: cancelled by the shutdown, where a
    // shutdown that waited for the job would send its result.
    let events = app.client.get(app.url(&format!("/v1/jobs/{id}/events"))).send().await.unwrap();
    let events = tokio::spawn(crate::helpers::read_events(events));
    app.shutdown().await;
    let events = events.await.unwrap();
    let last = events.last().expect("the stream ends with the job's final event");
    assert_eq!(last.event, "error", "{events:?}");
    let problem: Value = serde_json::from_str(&last.data).unwrap();
    assert_eq!(problem["type"], "/problems/job-cancelled", "{problem}");
}

#[tokio::test]
async fn the_page_and_its_assets_are_served_with_a_strict_content_policy() {
    let app = spawn_app().await;
    for (path, media) in [
        ("/", "text/html; charset=utf-8"),
        ("/assets/main.js", "text/javascript; charset=utf-8"),
        ("/assets/app.css", "text/css; charset=utf-8"),
    ] {
        let response = app.get(path).await;
        assert_eq!(response.status(), 200, "{path}");
        assert_eq!(response.headers()["content-type"], media, "{path}");
        let policy = response.headers()["content-security-policy"].to_str().unwrap().to_owned();
        assert!(policy.starts_with("default-src 'self'"), "{policy}");
        assert!(!response.text().await.unwrap().is_empty());
    }
    // The page loads only what the server serves.
    let html = app.get("/").await.text().await.unwrap();
    for asset in ["/assets/main.js", "/assets/app.css"] {
        assert!(html.contains(&format!("\"{asset}\"")), "the page refers to {asset}");
    }
    assert!(!html.contains("http://") && !html.contains("https://"), "no asset from elsewhere");
    // Every module the page imports, however deep, is served as JavaScript.
    let (mut queue, mut served) = (vec!["main.js".to_owned()], std::collections::BTreeSet::new());
    while let Some(module) = queue.pop() {
        if !served.insert(module.clone()) {
            continue;
        }
        let response = app.get(&format!("/assets/{module}")).await;
        assert_eq!(response.status(), 200, "{module}");
        assert_eq!(response.headers()["content-type"], "text/javascript; charset=utf-8", "{module}");
        let text = response.text().await.unwrap();
        for import in text.split("from \"./").skip(1) {
            queue.push(import[..import.find('"').unwrap()].to_owned());
        }
    }
    assert!(served.len() >= 8, "the page is its modules: {served:?}");
    let missing = app.get("/assets/nope.js").await;
    assert_eq!(missing.status(), 404);
    assert_eq!(missing.headers()["content-type"], "application/problem+json");
    app.shutdown().await;
}
