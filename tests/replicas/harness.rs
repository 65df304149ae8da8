//! A real `redis-server` and real meshfit processes on loopback ports, killed when dropped.

use reqwest::{Client, Response};
use serde_json::Value;
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Whether the tests may run: `redis-server` is installed. With `REDIS_TESTS=required` (as
/// in CI) a missing server fails the test instead of skipping it.
pub fn redis_available() -> bool {
    let found = Command::new("redis-server").arg("--version").output().is_ok_and(|o| o.status.success());
    if !found {
        assert_ne!(
            std::env::var("REDIS_TESTS").as_deref(),
            Ok("required"),
            "REDIS_TESTS=required but redis-server is not installed"
        );
        eprintln!("skipped: redis-server is not installed (apt-get install redis-server)");
    }
    found
}

/// A port free a moment ago (Redis takes a port number, not a listener).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

fn log_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("replicas");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A `redis-server` without persistence on a loopback port.
pub struct Redis {
    pub port: u16,
    child: Option<Child>,
}

impl Redis {
    pub async fn start() -> Self {
        let mut redis = Self { port: free_port(), child: None };
        redis.restart().await;
        redis
    }

    pub fn url(&self) -> String {
        format!("redis://127.0.0.1:{}/", self.port)
    }

    /// Starts the server (again, on the same port) and waits until it answers.
    pub async fn restart(&mut self) {
        let child = Command::new("redis-server")
            .args([
                "--port",
                &self.port.to_string(),
                "--bind",
                "127.0.0.1",
                "--save",
                "",
                "--appendonly",
                "no",
            ])
            .stdout(Stdio::null())
            .spawn()
            .expect("redis-server starts");
        self.child = Some(child);
        for _ in 0..200 {
            if tokio::net::TcpStream::connect(("127.0.0.1", self.port)).await.is_ok() {
                return;
            }
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
        panic!("redis-server did not listen on {}", self.port);
    }

    /// Kills the server at once.
    /// Waits until job `id` is listed as pending: its spec is kept for a takeover.
    pub async fn wait_pending(&self, id: &str) {
        let client = redis::Client::open(self.url()).unwrap();
        let mut conn = client.get_multiplexed_async_connection().await.unwrap();
        for _ in 0..1200 {
            let listed: bool =
                redis::cmd("SISMEMBER").arg("meshfit:pending").arg(id).query_async(&mut conn).await.unwrap();
            if listed {
                return;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!("job {id} was never listed as pending");
    }

    pub fn stop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Drop for Redis {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A meshfit process sharing through `redis`, with a short lease.
pub struct Replica {
    pub addr: String,
    pub client: Client,
    child: Child,
}

impl Replica {
    pub async fn start(name: &str, redis: &Redis) -> Self {
        Self::start_with(name, redis, &[]).await
    }

    /// A replica with `settings` over the defaults above.
    pub async fn start_with(name: &str, redis: &Redis, settings: &[(&str, &str)]) -> Self {
        let log = log_dir().join(format!("{name}-{}.log", redis.port));
        let file = std::fs::File::create(&log).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_meshfit"))
            .arg("serve")
            .env_clear()
            .env("MESHFIT_ADDR", "127.0.0.1:0")
            .env("MESHFIT_WORKERS", "1")
            .env("MESHFIT_MAX_VERTICES", "3000000")
            .env("MESHFIT_MEMORY_BYTES", (4u64 << 30).to_string())
            .env("MESHFIT_LOG_FORMAT", "json")
            .env("MESHFIT_SHUTDOWN_GRACE_MS", "500")
            .env("MESHFIT_REDIS_URL", redis.url())
            .env("MESHFIT_REDIS_LEASE_MS", "600")
            .envs(settings.iter().copied())
            .stdout(file.try_clone().unwrap())
            .stderr(file)
            .spawn()
            .expect("meshfit starts");
        for _ in 0..400 {
            let text = std::fs::read_to_string(&log).unwrap_or_default();
            let addr = text.lines().find_map(|line| {
                // JSON lines with the event's fields flattened (see `telemetry`).
                let entry: Value = serde_json::from_str(line).ok()?;
                (entry["message"] == "meshfit listening")
                    .then(|| entry["addr"].as_str().map(str::to_owned))?
            });
            if let Some(addr) = addr {
                let client = Client::builder().timeout(Duration::from_secs(120)).build().unwrap();
                let replica = Self { addr, client, child };
                // Until its first ping answers, a replica serves alone.
                replica.wait_redis("up").await;
                return replica;
            }
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
        let _ = child.kill();
        let _ = child.wait();
        panic!("{name} did not start; see {}", log.display());
    }

    pub fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }

    pub async fn get(&self, path: &str) -> Response {
        self.client.get(self.url(path)).send().await.expect("request sent")
    }

    pub async fn post(&self, path: &str, body: &Value) -> Response {
        self.client.post(self.url(path)).json(body).send().await.expect("request sent")
    }

    pub async fn status(&self, id: &str) -> Value {
        self.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap()
    }

    /// Polls `GET /v1/jobs/{id}` until `pred` holds for its status.
    pub async fn wait_status(&self, id: &str, pred: impl Fn(&str) -> bool) -> Value {
        for _ in 0..1200 {
            let response = self.get(&format!("/v1/jobs/{id}")).await;
            if response.status() == 200 {
                let status: Value = response.json().await.unwrap();
                if pred(status["status"].as_str().unwrap_or_default()) {
                    return status;
                }
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!("job {id} never reached the status waited for on {}", self.addr);
    }

    /// A sample of `/metrics` by its full name and labels.
    pub async fn metric(&self, sample: &str) -> f64 {
        let text = self.get("/metrics").await.text().await.unwrap();
        text.lines()
            .find_map(|line| line.strip_prefix(sample)?.strip_prefix(' ')?.trim().parse().ok())
            .unwrap_or(0.0)
    }

    /// What `/readyz` says of Redis, polled until it says `want`.
    pub async fn wait_redis(&self, want: &str) {
        for _ in 0..400 {
            let ready: Value = self.get("/readyz").await.json().await.unwrap();
            if ready["redis"] == want {
                return;
            }
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
        panic!("/readyz on {} never said redis {want}", self.addr);
    }

    /// SIGTERM, and waits for the process to end; says whether it exited cleanly.
    pub fn terminate(&mut self) -> bool {
        let pid = rustix::process::Pid::from_child(&self.child);
        rustix::process::kill_process(pid, rustix::process::Signal::TERM).expect("signal sent");
        self.child.wait().unwrap().success()
    }

    /// SIGKILL: no shutdown, no lease given back.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Replica {
    fn drop(&mut self) {
        self.kill();
    }
}

/// The body of a finite event stream, split into (event, data) pairs.
pub async fn events(response: Response) -> Vec<(String, String)> {
    assert_eq!(response.headers()["content-type"], "text/event-stream");
    let text = response.text().await.unwrap();
    text.split("\n\n")
        .filter_map(|block| {
            let (mut event, mut data) = (String::from("message"), Vec::new());
            for line in block.lines() {
                if let Some(v) = line.strip_prefix("event:") {
                    event = v.trim().to_owned();
                } else if let Some(v) = line.strip_prefix("data:") {
                    data.push(v.strip_prefix(' ').unwrap_or(v).to_owned());
                }
            }
            (!data.is_empty()).then(|| (event, data.join("\n")))
        })
        .collect()
}
