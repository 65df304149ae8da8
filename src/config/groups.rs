//! The settings as the service takes them: [`Config`], grouped by the part of the service
//! that takes each group, with its safe defaults.

use crate::datasets::DatasetSettings;
use crate::jobs::{CacheSettings, Pool};
use crate::spec::Limits;
use ipnet::IpNet;
use sha2::{Digest, Sha256};
use std::collections::HashSet;
use std::fmt;
use std::net::{IpAddr, SocketAddr};
use std::num::NonZeroUsize;
use std::time::Duration;

/// Log output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    /// Human-readable lines.
    Text,
    /// One JSON object per line.
    Json,
}

/// Where the server listens unless told otherwise: this machine only (a container sets
/// `0.0.0.0:8080`).
pub const DEFAULT_ADDR: SocketAddr = SocketAddr::new(IpAddr::V4(std::net::Ipv4Addr::LOCALHOST), 8080);

/// Validated service settings, each read from the variable of its [`Setting`](super::Setting) (named in
/// brackets); [`SETTINGS`](super::SETTINGS) holds their defaults and help. They arrive grouped by the part of
/// the service that takes them, so that wiring the server hands over groups and copies no
/// field.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Where to listen (`MESHFIT_ADDR`).
    pub addr: SocketAddr,
    /// Log lines as text or JSON (`MESHFIT_LOG_FORMAT`).
    pub log_format: LogFormat,
    /// Which log lines are written, in `RUST_LOG` syntax (`MESHFIT_LOG`).
    pub log_filter: String,
    /// How long running jobs may finish after SIGTERM (`MESHFIT_SHUTDOWN_GRACE_MS`).
    pub shutdown_grace: Duration,
    /// What one request may ask for (`MESHFIT_MAX_VERTICES`, `MESHFIT_MAX_GRID_POINTS`,
    /// `MESHFIT_MAX_EXPRESSION_LEN`, `MESHFIT_JOB_TIME_LIMIT_MS`).
    pub limits: Limits,
    /// The workers, the queue, each client's share and the memory budget.
    pub pool: Pool,
    /// Finished meshes kept in memory and on disk.
    pub cache: CacheSettings,
    /// Connections: how many, and how long they may take.
    pub connections: Connections,
    /// Request bodies: how large, and how slow.
    pub body: BodyLimits,
    /// Who may call the API, from which pages, through which proxies.
    pub callers: Callers,
    /// The Redis replicas share results and jobs through.
    pub redis: Redis,
    /// DEMs for terrain tiles: files named at start-up, room for uploads, the tiles' error and
    /// cache (`MESHFIT_DATASET`, `MESHFIT_DATASET_BYTES`, `MESHFIT_TILE_ERROR_FACTOR`,
    /// `MESHFIT_TILE_CACHE_BYTES`).
    pub datasets: DatasetSettings,
}

/// Connections: how many are served at once, and how long they may take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Connections {
    /// Connections served at once (`MESHFIT_MAX_CONNECTIONS`).
    pub max: usize,
    /// Time from the end of a response, or a connection's start, to the end of the next
    /// request's headers (`MESHFIT_HEADER_TIMEOUT_MS`).
    pub header_timeout: Duration,
    /// Longest a response may wait for the client to read (`MESHFIT_WRITE_TIMEOUT_MS`).
    pub write_timeout: Duration,
}

/// How large and how slow a request body may be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BodyLimits {
    /// Most bytes (`MESHFIT_MAX_BODY_BYTES`).
    pub max_bytes: usize,
    /// Longest pause (`MESHFIT_BODY_TIMEOUT_MS`); a body may also take no longer than this
    /// plus its length at 64 KiB/s.
    pub timeout: Duration,
}

/// Who may call the API.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Callers {
    /// API keys (`MESHFIT_API_KEYS`, `MESHFIT_API_KEYS_FILE`); none leaves the API open.
    pub api_keys: ApiKeys,
    /// Origins whose web pages may call the API (`MESHFIT_CORS_ORIGINS`).
    pub cors_origins: Vec<String>,
    /// Proxies whose forwarding headers name the client (`MESHFIT_TRUSTED_PROXIES`).
    pub trusted_proxies: Vec<IpNet>,
}

/// The Redis replicas share results and jobs through.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Redis {
    /// `redis://host:port/db` (`MESHFIT_REDIS_URL`); none, and this process serves alone.
    pub url: Option<String>,
    /// How long results, postings and requests stay (`MESHFIT_REDIS_TTL_MS`).
    pub ttl: Duration,
    /// The largest result (compact form) or request body kept; larger ones stay on the
    /// replica that made them (`MESHFIT_REDIS_MAX_BYTES`).
    pub max_bytes: u64,
    /// A job's lease: how long after its replica dies another takes it over
    /// (`MESHFIT_REDIS_LEASE_MS`). Renewed every third of it.
    pub lease: Duration,
}

/// Shortest API key accepted: a key is a secret, not a name.
pub const MIN_KEY_LEN: usize = 16;

/// The configured API keys, as digests. Empty: the API is open.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct ApiKeys(HashSet<[u8; 32]>);

impl ApiKeys {
    /// Adds a key.
    pub fn insert(&mut self, key: &str) {
        self.0.insert(Sha256::digest(key.as_bytes()).into());
    }

    /// How many keys there are.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether no key is configured (the API is open).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The name of the client a presented key identifies (`key:` and the start of its
    /// digest, never the key), if it is one of ours.
    pub fn client_name(&self, key: &str) -> Option<String> {
        let digest: [u8; 32] = Sha256::digest(key.as_bytes()).into();
        self.0.contains(&digest).then(|| {
            let name: String = digest[..6].iter().map(|b| format!("{b:02x}")).collect();
            format!("key:{name}")
        })
    }
}

/// Never prints a key or its digest.
impl fmt::Debug for ApiKeys {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ApiKeys({} configured)", self.0.len())
    }
}

/// The default cap on connections: the process's soft file limit less room for the cache
/// directory's files, the listener and the connections refused with a 503 beyond the cap
/// (256 in all), at most 10,000.
pub fn default_max_connections() -> usize {
    let soft = rustix::process::getrlimit(rustix::process::Resource::Nofile).current;
    let files = soft.map_or(usize::MAX, |n| usize::try_from(n).unwrap_or(usize::MAX));
    files.saturating_sub(256).clamp(16, 10_000)
}

/// The defaults. Those that are values are written again in [`SETTINGS`](super::SETTINGS), and a test checks
/// that the two agree.
impl Default for Config {
    fn default() -> Self {
        Self {
            addr: DEFAULT_ADDR,
            log_format: LogFormat::Text,
            log_filter: "info".to_owned(),
            shutdown_grace: Duration::from_secs(10),
            limits: Limits {
                max_vertices: 2_000_000,
                // 4097 × 4097: the largest grid of the README's benchmarks, and of many DEM tiles.
                max_grid_points: 4097 * 4097,
                max_expression_len: 4096,
                job_time_limit: Duration::from_secs(60),
            },
            pool: Pool {
                workers: std::thread::available_parallelism().unwrap_or(NonZeroUsize::MIN),
                queue: 64,
                client_share: 0.5,
                memory_bytes: crate::jobs::default_memory_bytes(),
                job_retention: Duration::from_secs(24 * 3600),
            },
            cache: CacheSettings { memory_bytes: 1 << 30, dir: None, dir_bytes: 10 << 30 },
            connections: Connections {
                max: default_max_connections(),
                header_timeout: Duration::from_secs(15),
                write_timeout: Duration::from_secs(30),
            },
            body: BodyLimits { max_bytes: 256 << 20, timeout: Duration::from_secs(15) },
            callers: Callers::default(),
            redis: Redis {
                url: None,
                ttl: Duration::from_secs(24 * 3600),
                max_bytes: 256 << 20,
                lease: Duration::from_secs(10),
            },
            datasets: DatasetSettings::default(),
        }
    }
}
