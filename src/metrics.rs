//! Prometheus metrics, served as text at `GET /metrics`.
//!
//! prometheus-client is the Prometheus project's own Rust client: typed metric families and
//! the text exposition format, without a global registry.

use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::{Histogram, exponential_buckets};
use prometheus_client::registry::Registry;

/// Labels of finished jobs.
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct StateLabel {
    /// succeeded, failed, cancelled, or handed_back (to another replica, at shutdown).
    pub state: &'static str,
}

/// Labels of HTTP requests.
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct RequestLabels {
    /// The HTTP method: GET, POST, DELETE, HEAD or OTHER.
    pub method: &'static str,
    /// The status code.
    pub status: u16,
}

/// Every metric the service exports.
pub struct Metrics {
    registry: Registry,
    /// Jobs waiting for a worker.
    pub jobs_queued: Gauge,
    /// Jobs refining now.
    pub jobs_running: Gauge,
    /// Jobs finished, by final state.
    pub jobs_finished: Family<StateLabel, Counter>,
    /// Refinements started (a cache hit or a joined job starts none).
    pub engine_runs: Counter,
    /// Requests answered from the cache.
    pub cache_hits: Counter,
    /// Requests answered by replaying a larger cached run of the same family.
    pub prefix_hits: Counter,
    /// Requests that had to compute (or join a computation).
    pub cache_misses: Counter,
    /// Bytes of meshes held in memory.
    pub cache_bytes: Gauge,
    /// Bytes of the mesh files this server has indexed in the cache directory.
    pub cache_disk_bytes: Gauge,
    /// Requests, by method and status.
    pub http_requests: Family<RequestLabels, Counter>,
    /// Request latency until the response head, in seconds.
    pub http_latency: Histogram,
    /// The memory budget in bytes.
    pub memory_budget_bytes: Gauge,
    /// Bytes charged to the budget by bodies and jobs (the cache's are `cache_bytes`).
    pub memory_charged_bytes: Gauge,
    /// Requests refused because they did not fit in the memory budget.
    pub memory_refusals: Counter,
    /// Connections open now, past the cap included.
    pub connections_open: Gauge,
    /// Connections refused for the cap (answered with a 503, or closed at once).
    pub connections_refused: Counter,
    /// Results read from Redis: made by another replica.
    pub shared_hits: Counter,
    /// Jobs followed here while another replica runs them.
    pub jobs_followed: Counter,
    /// Jobs taken over from a replica that stopped renewing its lease.
    pub takeovers: Counter,
    /// 1 when the last command reached Redis, 0 when it did not; absent without Redis.
    pub redis_up: Gauge,
    /// Redis commands that failed.
    pub redis_errors: Counter,
}

impl Default for Metrics {
    fn default() -> Self {
        let mut registry = Registry::with_prefix("meshfit");
        let m = Self {
            jobs_queued: Gauge::default(),
            jobs_running: Gauge::default(),
            jobs_finished: Family::default(),
            engine_runs: Counter::default(),
            cache_hits: Counter::default(),
            prefix_hits: Counter::default(),
            cache_misses: Counter::default(),
            cache_bytes: Gauge::default(),
            cache_disk_bytes: Gauge::default(),
            http_requests: Family::default(),
            http_latency: Histogram::new(exponential_buckets(0.0005, 4.0, 10)),
            memory_budget_bytes: Gauge::default(),
            memory_charged_bytes: Gauge::default(),
            memory_refusals: Counter::default(),
            connections_open: Gauge::default(),
            connections_refused: Counter::default(),
            shared_hits: Counter::default(),
            jobs_followed: Counter::default(),
            takeovers: Counter::default(),
            redis_up: Gauge::default(),
            redis_errors: Counter::default(),
            registry: Registry::default(),
        };
        registry.register("jobs_queued", "Jobs waiting for a worker", m.jobs_queued.clone());
        registry.register("jobs_running", "Jobs refining now", m.jobs_running.clone());
        registry.register("jobs_finished", "Jobs finished, by final state", m.jobs_finished.clone());
        registry.register("engine_runs", "Refinements started", m.engine_runs.clone());
        registry.register("cache_hits", "Requests answered from the cache", m.cache_hits.clone());
        registry.register(
            "prefix_hits",
            "Requests answered by replaying a larger cached run",
            m.prefix_hits.clone(),
        );
        registry.register("cache_misses", "Requests not answered from the cache", m.cache_misses.clone());
        registry.register("cache_bytes", "Bytes of meshes held in memory", m.cache_bytes.clone());
        registry.register(
            "cache_disk_bytes",
            "Bytes of the mesh files this server has indexed in the cache directory",
            m.cache_disk_bytes.clone(),
        );
        registry.register("http_requests", "HTTP requests by method and status", m.http_requests.clone());
        registry.register(
            "http_request_duration_seconds",
            "Time to the response head",
            m.http_latency.clone(),
        );
        registry.register(
            "memory_budget_bytes",
            "The memory budget (MESHFIT_MEMORY_BYTES)",
            m.memory_budget_bytes.clone(),
        );
        registry.register(
            "memory_charged_bytes",
            "Bytes of the budget charged to request bodies and jobs; cached meshes are cache_bytes",
            m.memory_charged_bytes.clone(),
        );
        registry.register(
            "memory_refusals",
            "Requests refused because they did not fit in the memory budget",
            m.memory_refusals.clone(),
        );
        registry.register("connections_open", "Connections open now", m.connections_open.clone());
        registry.register(
            "connections_refused",
            "Connections refused because MESHFIT_MAX_CONNECTIONS were open",
            m.connections_refused.clone(),
        );
        registry.register(
            "shared_hits",
            "Results read from Redis, made by another replica",
            m.shared_hits.clone(),
        );
        registry.register(
            "jobs_followed",
            "Jobs followed here while another replica runs them",
            m.jobs_followed.clone(),
        );
        registry.register(
            "takeovers",
            "Jobs taken over from a replica whose lease expired",
            m.takeovers.clone(),
        );
        registry.register("redis_errors", "Redis commands that failed", m.redis_errors.clone());
        Self { registry, ..m }
    }
}

impl Metrics {
    /// Adds `redis_up`, for a replica that shares through Redis: a replica without Redis has
    /// no such gauge, rather than one that reads 0.
    pub fn register_redis(&mut self) {
        self.registry.register(
            "redis_up",
            "1 when the last Redis command succeeded, else 0",
            self.redis_up.clone(),
        );
    }

    /// The text exposition format.
    pub fn encode(&self) -> String {
        let mut out = String::new();
        prometheus_client::encoding::text::encode(&mut out, &self.registry).expect("writing to a String");
        out
    }
}
