//! The disk cache: results survive a restart; a corrupt file is recomputed, never served.

use crate::helpers::{spawn_with, temp_dir, test_config};
use serde_json::{Value, json};

fn with_dir(dir: &std::path::Path) -> meshfit::config::Config {
    let mut config = test_config();
    config.cache.dir = Some(dir.to_owned());
    config
}

#[tokio::test]
async fn a_restart_with_a_cache_dir_serves_the_old_result_without_recomputing() {
    let dir = temp_dir("restart");
    let body = json!({"function": "cos(4*x*y)", "max_vertices": 5000});
    let first = spawn_with(with_dir(&dir)).await;
    let original = first.post("/v1/meshes", &body).await.bytes().await.unwrap();
    first.shutdown().await;

    let second = spawn_with(with_dir(&dir)).await;
    let response = second.post("/v1/meshes", &body).await;
    assert_eq!(response.headers()["x-cache"], "hit");
    assert_eq!(response.bytes().await.unwrap(), original);
    assert_eq!(second.metric("meshfit_engine_runs_total").await, 0.0);
    // Status and mesh endpoints find it too, with no job record in this process.
    let id = serde_json::from_slice::<Value>(&original).unwrap()["id"].as_str().unwrap().to_owned();
    let status: Value = second.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    assert_eq!(status["status"], "succeeded");
    // The run's trace came back from disk with it: a smaller budget is replayed, not run.
    let smaller = second.post("/v1/meshes", &json!({"function": "cos(4*x*y)", "max_vertices": 1200})).await;
    assert_eq!(smaller.headers()["x-cache"], "prefix");
    assert_eq!(second.metric("meshfit_engine_runs_total").await, 0.0);
    second.shutdown().await;
}

#[tokio::test]
async fn a_corrupt_cache_file_is_recomputed_not_served() {
    let dir = temp_dir("corrupt");
    let body = json!({"function": "x^3 - y", "max_vertices": 3000});
    let first = spawn_with(with_dir(&dir)).await;
    let original: Value = first.post("/v1/meshes", &body).await.json().await.unwrap();
    first.shutdown().await;

    let file = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "mesh"))
        .unwrap();
    let mut bytes = std::fs::read(&file).unwrap();
    let n = bytes.len();
    bytes[n - 20] ^= 0x20;
    std::fs::write(&file, bytes).unwrap();

    let second = spawn_with(with_dir(&dir)).await;
    let response = second.post("/v1/meshes", &body).await;
    assert_eq!(response.headers()["x-cache"], "miss");
    let recomputed: Value = response.json().await.unwrap();
    assert_eq!(second.metric("meshfit_engine_runs_total").await, 1.0);
    assert_eq!(recomputed["vertices"], original["vertices"]);
    assert_eq!(recomputed["triangles"], original["triangles"]);
    second.shutdown().await;
}

#[tokio::test]
async fn the_cache_directory_stays_within_its_byte_limit_keeping_what_is_in_use() {
    let dir = temp_dir("limit");
    let mut config = with_dir(&dir);
    // Room for about three of these meshes with their traces (some 75 kB each).
    config.cache.dir_bytes = 250_000;
    let app = spawn_with(config).await;
    let mesh = |n: u32| json!({"function": "x*y", "max_vertices": n});
    let first: Value = app.post("/v1/meshes", &mesh(500)).await.json().await.unwrap();
    let first = first["id"].as_str().unwrap().to_owned();
    for n in [510, 520, 530] {
        assert_eq!(app.post("/v1/meshes", &mesh(n)).await.status(), 200);
        // Asked for again, from memory: its file is the most recently used.
        assert_eq!(app.post("/v1/meshes", &mesh(500)).await.headers()["x-cache"], "hit");
    }
    let files: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap()).collect();
    let total: u64 = files.iter().map(|f| f.metadata().unwrap().len()).sum();
    assert!(total <= 250_000 && files.len() < 4, "{} files, {total} bytes", files.len());
    assert!(
        files.iter().any(|f| f.file_name().to_string_lossy().starts_with(&first)),
        "the mesh in use is kept"
    );
    assert_eq!(app.metric("meshfit_cache_disk_bytes").await, total as f64);
    app.shutdown().await;
}

#[tokio::test]
async fn a_cache_directory_that_stops_taking_files_loses_no_answer() {
    let dir = temp_dir("unwritable");
    let app = spawn_with(with_dir(&dir)).await;
    // Once the server answers it has opened the directory (a path it cannot use at start-up
    // stops it, see tests/cli.rs); then the directory goes away and a file takes its place:
    // every write into it fails.
    assert_eq!(app.get("/healthz").await.status(), 200);
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::write(&dir, b"in the way").unwrap();
    let body = json!({"function": "x*exp(y)", "max_vertices": 3000});
    let first = app.post("/v1/meshes", &body).await;
    assert_eq!(first.status(), 200);
    let first = first.bytes().await.unwrap();
    let again = app.post("/v1/meshes", &body).await;
    assert_eq!(again.headers()["x-cache"], "hit", "kept in memory");
    assert_eq!(again.bytes().await.unwrap(), first);
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 1.0);
    app.shutdown().await;
    std::fs::remove_file(&dir).unwrap();
}
