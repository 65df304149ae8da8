//! API keys, origins and each client's share of the workers and the queue.

use crate::helpers::{TestApp, configured, spawn_with, test_config};
use meshfit::config::ApiKeys;
use meshfit::config::Config;
use serde_json::{Value, json};

const KEY_A: &str = "key-a-0123456789abcdef";
const KEY_B: &str = "key-b-0123456789abcdef";

fn with_keys(mut config: Config) -> Config {
    let mut keys = ApiKeys::default();
    keys.insert(KEY_A);
    keys.insert(KEY_B);
    config.callers.api_keys = keys;
    config
}

async fn post_as(app: &TestApp, key: &str, path: &str, body: &Value) -> reqwest::Response {
    app.client.post(app.url(path)).bearer_auth(key).json(body).send().await.unwrap()
}

async fn status_as(app: &TestApp, key: &str, id: &str) -> Value {
    let response = app.client.get(app.url(&format!("/v1/jobs/{id}"))).bearer_auth(key).send().await.unwrap();
    response.json().await.unwrap()
}

#[tokio::test]
async fn with_keys_every_v1_route_needs_one_and_health_stays_open() {
    let app = spawn_with(with_keys(test_config())).await;
    let body = json!({"function": "x*y", "max_vertices": 50});
    let missing = app.post("/v1/meshes", &body).await;
    assert_eq!(missing.status(), 401);
    assert_eq!(missing.headers()["www-authenticate"], "Bearer");
    assert_eq!(missing.json::<Value>().await.unwrap()["type"], "/problems/unauthorized");
    let wrong = post_as(&app, "key-c-0123456789abcdef", "/v1/meshes", &body).await;
    assert_eq!(wrong.status(), 401);
    assert_eq!(app.get("/v1/jobs/0123").await.status(), 401, "reads need a key too");
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 0.0);

    let ok = post_as(&app, KEY_A, "/v1/meshes", &body).await;
    assert_eq!(ok.status(), 200);
    for open in ["/healthz", "/readyz", "/metrics", "/openapi.yaml"] {
        assert_eq!(app.get(open).await.status(), 200, "{open}");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn a_page_of_another_origin_cannot_submit_jobs_unless_listed() {
    let config = configured(|c| c.callers.cors_origins = vec!["https://app.example".into()]);
    let app = spawn_with(config).await;
    let body = r#"{"function": "x+y", "max_vertices": 50}"#;
    let from = |origin: &str, content_type: &str| {
        let request = app.client.post(app.url("/v1/jobs")).header("content-type", content_type);
        request.header("origin", origin).body(body).send()
    };
    // What a form or fetch without preflight sends: text/plain, with the page's origin. It is
    // refused for its origin before its content type is looked at.
    let foreign = from("https://evil.example", "text/plain").await.unwrap();
    assert_eq!(foreign.status(), 403);
    assert_eq!(foreign.json::<Value>().await.unwrap()["type"], "/problems/cross-origin");
    assert_eq!(app.metric("meshfit_cache_misses_total").await, 0.0, "no job was looked up or made");

    // A listed origin passes; its body is JSON, and a text/plain one is refused as such.
    let plain = from("https://app.example", "text/plain").await.unwrap();
    assert_eq!(plain.status(), 415);
    let listed = from("https://app.example", "application/json").await.unwrap();
    assert_eq!(listed.status(), 202);
    assert_eq!(listed.headers()["access-control-allow-origin"], "https://app.example");
    assert!(listed.headers()["access-control-expose-headers"].to_str().unwrap().contains("location"));
    let own = from(&format!("http://{}", app.addr), "application/json").await.unwrap();
    // The server's own page: the same job, joined (202) or finished (200), never refused.
    assert!(matches!(own.status().as_u16(), 200 | 202), "{}", own.status());

    let preflight = app
        .client
        .request(reqwest::Method::OPTIONS, app.url("/v1/meshes"))
        .header("origin", "https://app.example")
        .header("access-control-request-method", "POST")
        .header("access-control-request-headers", "content-type,authorization")
        .send()
        .await
        .unwrap();
    assert!(preflight.status().is_success());
    assert!(preflight.headers()["access-control-allow-methods"].to_str().unwrap().contains("POST"));
    app.shutdown().await;
}

#[tokio::test]
async fn one_client_uses_idle_workers_but_not_the_whole_queue_and_others_run_first() {
    // Two workers and a queue of 8: each key may hold 5 jobs, and runs 1 before others' go first.
    let app = spawn_with(with_keys(configured(|c| c.pool.client_share = 0.5))).await;
    let long = |i: usize| json!({"function": format!("sin(40*x)*cos(40*y)+{i}"), "max_vertices": 2_000_000});
    let mut ids = Vec::new();
    for i in 0..5 {
        let status: Value = post_as(&app, KEY_A, "/v1/jobs", &long(i)).await.json().await.unwrap();
        ids.push(status["id"].as_str().unwrap().to_owned());
    }
    // No other client waits, so A's second job takes the second worker instead of idling it.
    for id in &ids[..2] {
        while status_as(&app, KEY_A, id).await["status"] != "running" {
            tokio::time::sleep(std::time::Duration::from_millis(10)).await;
        }
    }
    let refused = post_as(&app, KEY_A, "/v1/jobs", &long(5)).await;
    assert_eq!(refused.status(), 429);
    assert!(refused.headers()["retry-after"].to_str().unwrap().parse::<u64>().unwrap() >= 1);
    let problem: Value = refused.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/share-used");

    // B's job arrives behind three of A's queued ones and runs at once, before them: B runs
    // below its share and A above it, so one of A's runs pauses for it.
    let small: Value = post_as(&app, KEY_B, "/v1/jobs", &json!({"function": "x*y", "max_vertices": 10}))
        .await
        .json()
        .await
        .unwrap();
    let small = small["id"].as_str().unwrap();
    while status_as(&app, KEY_B, small).await["status"] != "succeeded" {
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    // A's two runs go on (the paused one first), and A's queued ones still wait.
    for id in &ids[..2] {
        assert_eq!(status_as(&app, KEY_A, id).await["status"], "running");
    }
    for id in &ids[2..] {
        assert_eq!(status_as(&app, KEY_A, id).await["status"], "queued");
    }
    for id in &ids {
        app.client.delete(app.url(&format!("/v1/jobs/{id}"))).bearer_auth(KEY_A).send().await.unwrap();
    }
    app.shutdown().await;
}

#[tokio::test]
async fn behind_a_trusted_proxy_each_forwarded_address_is_its_own_client() {
    let config = configured(|c| {
        c.pool.client_share = 0.5;
        c.callers.trusted_proxies = vec!["127.0.0.1/32".parse().unwrap()];
    });
    let app = spawn_with(config).await;
    let long = |i: usize| json!({"function": format!("sin(41*x)*cos(41*y)+{i}"), "max_vertices": 2_000_000});
    let post = |from: &'static str, body: Value| {
        let request = app.client.post(app.url("/v1/jobs")).header("x-forwarded-for", from).json(&body);
        async move { request.send().await.unwrap() }
    };
    let mut ids = Vec::new();
    for i in 0..5 {
        let status: Value = post("203.0.113.1", long(i)).await.json().await.unwrap();
        ids.push(status["id"].as_str().unwrap().to_owned());
    }
    assert_eq!(post("203.0.113.1", long(5)).await.status(), 429, "the first caller holds its share");
    let other = post("198.51.100.7, 127.0.0.1", long(6)).await;
    assert_eq!(other.status(), 202, "another caller behind the same proxy is another client");
    let other: Value = other.json().await.unwrap();
    ids.push(other["id"].as_str().unwrap().to_owned());
    for id in &ids {
        app.client.delete(app.url(&format!("/v1/jobs/{id}"))).send().await.unwrap();
    }
    app.shutdown().await;
}

#[tokio::test]
async fn with_keys_the_job_list_shows_each_client_its_own_jobs() {
    let app = spawn_with(with_keys(test_config())).await;
    let shared = json!({"function": "x + y", "max_vertices": 40});
    let a_only = json!({"function": "x - y", "max_vertices": 40});
    for (key, body) in [(KEY_A, &shared), (KEY_A, &a_only), (KEY_B, &shared)] {
        let status: Value = post_as(&app, key, "/v1/jobs", body).await.json().await.unwrap();
        let id = status["id"].as_str().unwrap().to_owned();
        while status_as(&app, key, &id).await["status"] != "succeeded" {
            tokio::time::sleep(std::time::Duration::from_millis(10)).await;
        }
    }
    let list = |key: &'static str| {
        let app = &app;
        async move {
            let response = app.client.get(app.url("/v1/jobs")).bearer_auth(key).send().await.unwrap();
            let doc: Value = response.json().await.unwrap();
            doc["jobs"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| j["id"].as_str().unwrap().to_owned())
                .collect::<Vec<_>>()
        }
    };
    let (a, b) = (list(KEY_A).await, list(KEY_B).await);
    assert_eq!(a.len(), 2, "{a:?}");
    assert_eq!(b.len(), 1, "{b:?}");
    assert_eq!(b[0], a[1], "the job both asked for is in both lists");
    app.shutdown().await;
}

#[tokio::test]
async fn a_client_below_its_share_runs_at_once_while_another_fills_every_worker() {
    // Two workers, a share of one each: A's two long jobs fill both.
    let app = spawn_with(configured(|c| {
        *c = with_keys(c.clone());
        c.pool.client_share = 0.5;
    }))
    .await;
    let long = |k: u32| json!({"function": format!("sin(30*x)*cos(30*y) + {k}"), "max_vertices": 300_000});
    let mut a_ids = Vec::new();
    for k in 0..2 {
        let status: Value = post_as(&app, KEY_A, "/v1/jobs", &long(k)).await.json().await.unwrap();
        a_ids.push(status["id"].as_str().unwrap().to_owned());
    }
    for id in &a_ids {
        while status_as(&app, KEY_A, id).await["status"] != "running" {
            tokio::time::sleep(std::time::Duration::from_millis(5)).await;
        }
    }
    // B's small job is answered while both of A's still run: one of them paused for it.
    let b = post_as(&app, KEY_B, "/v1/meshes", &json!({"function": "x*y", "max_vertices": 10})).await;
    assert_eq!(b.status(), 200);
    for id in &a_ids {
        assert_eq!(status_as(&app, KEY_A, id).await["status"], "running", "B did not wait for A's jobs");
    }
    // The paused run ends with the bytes of a run nobody paused.
    let mut paused = Vec::new();
    for id in &a_ids {
        while status_as(&app, KEY_A, id).await["status"] != "succeeded" {
            tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        }
        let url = app.url(&format!("/v1/jobs/{id}/mesh?format=ply"));
        paused.push(app.client.get(url).bearer_auth(KEY_A).send().await.unwrap().bytes().await.unwrap());
    }
    app.shutdown().await;
    let alone = crate::helpers::spawn_app().await;
    for (k, bytes) in paused.iter().enumerate() {
        let fresh = alone.post("/v1/meshes?format=ply", &long(k as u32)).await.bytes().await.unwrap();
        assert!(fresh == *bytes, "job {k}: the same bytes as an unpaused run");
    }
    alone.shutdown().await;
}
