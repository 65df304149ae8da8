//! `spawn_app()`: a real server on 127.0.0.1:0 with small limits, and request helpers.

use meshfit::config::{BodyLimits, Callers, Config, Connections, Redis};
use meshfit::datasets::DatasetSettings;
use meshfit::jobs::{CacheSettings, Pool};
use meshfit::spec::Limits;
use reqwest::{Client, Response};
use serde_json::Value;
use std::net::SocketAddr;
use std::num::NonZeroUsize;
use std::path::PathBuf;
use std::time::Duration;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

pub struct TestApp {
    pub addr: SocketAddr,
    pub client: Client,
    stop: Option<oneshot::Sender<()>>,
    server: Option<JoinHandle<std::io::Result<()>>>,
}

/// Settings for tests: loopback, port 0, two workers, a short queue; never the environment.
pub fn test_config() -> Config {
    Config {
        addr: SocketAddr::from(([127, 0, 0, 1], 0)),
        log_format: meshfit::config::LogFormat::Text,
        log_filter: "info".to_owned(),
        shutdown_grace: Duration::from_secs(2),
        limits: Limits {
            max_vertices: 2_000_000,
            max_grid_points: 10_000,
            max_expression_len: 200,
            job_time_limit: Duration::from_secs(30),
        },
        // Every test client is 127.0.0.1: a whole share keeps the tests of the queue simple.
        pool: Pool {
            workers: NonZeroUsize::new(2).unwrap(),
            queue: 8,
            client_share: 1.0,
            memory_bytes: 4 << 30,
            job_retention: Duration::from_secs(3600),
        },
        cache: CacheSettings { memory_bytes: 256 << 20, dir: None, dir_bytes: 64 << 20 },
        connections: Connections {
            max: 256,
            header_timeout: Duration::from_secs(30),
            write_timeout: Duration::from_secs(30),
        },
        body: BodyLimits { max_bytes: 1 << 20, timeout: Duration::from_secs(30) },
        callers: Callers::default(),
        redis: Redis {
            url: None,
            ttl: Duration::from_secs(3600),
            max_bytes: 64 << 20,
            lease: Duration::from_secs(10),
        },
        datasets: DatasetSettings::default(),
    }
}

/// [`test_config`] as `change` leaves it.
pub fn configured(change: impl FnOnce(&mut Config)) -> Config {
    let mut config = test_config();
    change(&mut config);
    config
}

pub async fn spawn_app() -> TestApp {
    spawn_with(test_config()).await
}

pub async fn spawn_with(config: Config) -> TestApp {
    let listener = tokio::net::TcpListener::bind(config.addr).await.expect("bind loopback");
    let addr = listener.local_addr().unwrap();
    let (stop, stopped) = oneshot::channel::<()>();
    let server = tokio::spawn(meshfit::serve(listener, config, async move {
        let _ = stopped.await;
    }));
    let client = Client::builder().timeout(Duration::from_secs(60)).build().unwrap();
    TestApp { addr, client, stop: Some(stop), server: Some(server) }
}

/// A directory under the target dir, empty, unique to `name`.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("api-{name}"));
    // A test may have left a file in the directory's place.
    let _ = std::fs::remove_dir_all(&dir).or_else(|_| std::fs::remove_file(&dir));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

impl TestApp {
    pub fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }

    pub async fn post(&self, path: &str, body: &Value) -> Response {
        self.client.post(self.url(path)).json(body).send().await.expect("request sent")
    }

    pub async fn post_raw(&self, path: &str, body: impl Into<reqwest::Body>) -> Response {
        let request = self.client.post(self.url(path)).header("content-type", "application/json");
        request.body(body).send().await.expect("request sent")
    }

    pub async fn get(&self, path: &str) -> Response {
        self.client.get(self.url(path)).send().await.expect("request sent")
    }

    pub async fn delete(&self, path: &str) -> Response {
        self.client.delete(self.url(path)).send().await.expect("request sent")
    }

    /// Polls `GET /v1/jobs/{id}` until its status is not queued or running.
    pub async fn wait_finished(&self, id: &str) -> Value {
        for _ in 0..600 {
            let status: Value = self.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
            if !matches!(status["status"].as_str(), Some("queued" | "running")) {
                return status;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!("job {id} did not finish within 30 s");
    }

    /// Polls until the job is running.
    pub async fn wait_running(&self, id: &str) {
        for _ in 0..600 {
            let status: Value = self.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
            if status["status"] == "running" {
                return;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        panic!("job {id} never started running");
    }

    /// A sample of `/metrics` by its full name and labels, e.g. `meshfit_engine_runs_total`.
    pub async fn metric(&self, sample: &str) -> f64 {
        let text = self.get("/metrics").await.text().await.unwrap();
        text.lines()
            .find_map(|line| line.strip_prefix(sample)?.strip_prefix(' ')?.trim().parse().ok())
            .unwrap_or(0.0)
    }

    /// Stops the server as SIGTERM would and waits for it to return.
    pub async fn shutdown(mut self) {
        let _ = self.stop.take().unwrap().send(());
        self.server.take().unwrap().await.unwrap().unwrap();
    }
}

/// One server-sent event.
#[derive(Debug, Clone, PartialEq)]
pub struct SseEvent {
    pub event: String,
    pub id: Option<u64>,
    pub data: String,
}

/// Reads a finite event stream to its end and splits it into events (comments dropped).
pub async fn read_events(response: Response) -> Vec<SseEvent> {
    assert_eq!(response.headers()["content-type"], "text/event-stream");
    let text = response.text().await.unwrap();
    text.split("\n\n")
        .filter_map(|block| {
            let (mut event, mut id, mut data) = (String::from("message"), None, Vec::new());
            for line in block.lines() {
                if let Some(v) = line.strip_prefix("event:") {
                    event = v.trim().to_owned();
                } else if let Some(v) = line.strip_prefix("id:") {
                    id = v.trim().parse().ok();
                } else if let Some(v) = line.strip_prefix("data:") {
                    data.push(v.strip_prefix(' ').unwrap_or(v).to_owned());
                }
            }
            (!data.is_empty()).then(|| SseEvent { event, id, data: data.join("\n") })
        })
        .collect()
}
