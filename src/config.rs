//! Service settings: environment variables (`MESHFIT_*`) over safe defaults, validated once.
//!
//! Two stages, as ripgrep's LowArgs/HiArgs: [`RawConfig`] holds the strings as given,
//! [`Config`] the typed values. Nothing downstream parses a string. Each setting is declared
//! once, in [`SETTINGS`]: its variable, flag, default, help and parser; `meshfit serve`'s flags
//! and `--help` are made from it, and tests hold the README's table and the defaults to it.

use crate::jobs::{CacheSettings, Pool};
use crate::spec::Limits;
use ipnet::IpNet;
use sha2::{Digest, Sha256};
use std::collections::{BTreeMap, HashSet};
use std::fmt;
use std::net::{IpAddr, SocketAddr};
use std::num::NonZeroUsize;
use std::path::PathBuf;
use std::time::Duration;

/// Log output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    /// Human-readable lines.
    Text,
    /// One JSON object per line.
    Json,
}

/// Where the server listens unless told otherwise.
pub const DEFAULT_ADDR: SocketAddr = SocketAddr::new(IpAddr::V4(std::net::Ipv4Addr::UNSPECIFIED), 8080);

/// Validated service settings, each read from the variable of its [`Setting`] (named in
/// brackets); [`SETTINGS`] holds their defaults and help. They arrive grouped by the part of
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

/// The defaults. Those that are values are written again in [`SETTINGS`], and a test checks
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
        }
    }
}

/// The settings as strings, keyed by variable name, before validation.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RawConfig {
    /// Values by variable name.
    values: BTreeMap<String, String>,
    /// The flag that gave a value, by variable name.
    flags: BTreeMap<String, &'static str>,
}

impl RawConfig {
    /// Every `MESHFIT_*` variable of the process environment.
    pub fn from_env() -> Self {
        std::env::vars().filter(|(k, _)| k.starts_with("MESHFIT_")).collect()
    }

    /// Sets one variable.
    pub fn set(&mut self, name: &str, value: impl Into<String>) {
        self.values.insert(name.to_owned(), value.into());
        self.flags.remove(name);
    }

    /// Sets `setting` from its command-line flag (flags override the environment), so that a
    /// bad value is reported under the flag the user typed.
    pub fn set_from_flag(&mut self, setting: &'static Setting, value: impl Into<String>) {
        self.set(setting.name, value);
        if let Some(flag) = setting.flag {
            self.flags.insert(setting.name.to_owned(), flag);
        }
    }
}

impl FromIterator<(String, String)> for RawConfig {
    fn from_iter<I: IntoIterator<Item = (String, String)>>(pairs: I) -> Self {
        Self { values: pairs.into_iter().collect(), flags: BTreeMap::new() }
    }
}

/// One invalid setting: where it came from, its value (or `<hidden>` for a secret) and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigProblem {
    /// The variable, e.g. `MESHFIT_WORKERS`.
    pub name: String,
    /// The flag it was given with, without its dashes (`workers`), if it was.
    pub flag: Option<&'static str>,
    /// The value as given, quoted, or `<hidden>`.
    pub shown: String,
    /// What is wrong with it.
    pub why: String,
}

impl std::fmt::Display for ConfigProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let Self { name, flag, shown, why } = self;
        match flag {
            Some(flag) => write!(f, "--{flag} {shown} ({name}): {why}"),
            None => write!(f, "{name}={shown}: {why}"),
        }
    }
}

/// Every invalid setting, each naming its variable (or flag) and value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid configuration:\n  {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n  "))]
pub struct ConfigError(pub Vec<ConfigProblem>);

/// One setting, declared once: the environment variable, the `meshfit serve` flag, its
/// default and help (which `--help` and the README's table show) and its parser. The README's
/// table is checked against [`SETTINGS`] by a test, and each default that is a value against
/// [`Config::default`].
pub struct Setting {
    /// The environment variable, `MESHFIT_WORKERS`.
    pub name: &'static str,
    /// The flag of `meshfit serve` without its dashes; none for a value that would show in
    /// the process list (keys) or that the log subscriber reads itself.
    pub flag: Option<&'static str>,
    /// What the value is, in `--help`: `N`, `MS`, `BYTES`.
    pub value_name: &'static str,
    /// The default.
    pub default: Fallback,
    /// What it does, in a sentence or two.
    pub help: &'static str,
    /// Reads the trimmed value into a config.
    parse: fn(&str, &mut Config) -> Result<(), String>,
}

/// A setting's default: a value the parser takes, or what it is when it depends on the machine
/// or means "off".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fallback {
    /// This value, as it would be written.
    Value(&'static str),
    /// Described, not written: "available cores", "unset".
    Described(&'static str),
}

impl std::fmt::Display for Fallback {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Fallback::Value(v) | Fallback::Described(v) => f.write_str(v),
        }
    }
}

impl Setting {
    /// The setting whose variable is `name`.
    pub fn named(name: &str) -> Option<&'static Setting> {
        SETTINGS.iter().find(|s| s.name == name)
    }

    /// The line `meshfit serve --help` shows for its flag.
    pub fn flag_help(&self) -> String {
        format!("{}: {} [default: {}]", self.name, self.help, self.default)
    }

    /// Whether the value is a secret: a bad one is reported by name, never echoed.
    fn is_secret(&self) -> bool {
        matches!(self.name, "MESHFIT_API_KEYS" | "MESHFIT_REDIS_URL")
    }
}

/// A whole number; `_` may group digits (`2_000_000`).
fn number(v: &str) -> Result<u64, String> {
    v.replace('_', "").parse::<u64>().map_err(|_| "expected a whole number".to_owned())
}

/// A whole number of at least `min`.
fn at_least(v: &str, min: u64) -> Result<u64, String> {
    number(v).and_then(|n| if n >= min { Ok(n) } else { Err(format!("must be at least {min}")) })
}

/// The non-blank items of a comma-separated list, each read by `item`; `expected` says what
/// it takes when one is not.
fn comma_separated<T>(v: &str, item: impl Fn(&str) -> Option<T>, expected: &str) -> Result<Vec<T>, String> {
    v.split(',')
        .map(str::trim)
        .filter(|i| !i.is_empty())
        .map(|i| item(i).ok_or_else(|| expected.to_owned()))
        .collect()
}

/// Milliseconds, at least `min`.
fn millis(v: &str, min: u64) -> Result<Duration, String> {
    at_least(v, min).map(Duration::from_millis)
}

/// Every setting, in the order the README's table and `--help` list them.
pub const SETTINGS: &[Setting] = &[
    Setting {
        name: "MESHFIT_ADDR",
        flag: Some("addr"),
        value_name: "HOST:PORT",
        default: Fallback::Value("0.0.0.0:8080"),
        help: "listen address: `host:port`, an address or a host name (`localhost:8080`)",
        parse: |v, c| listen_addr(v).map(|a| c.addr = a).map_err(str::to_owned),
    },
    Setting {
        name: "MESHFIT_WORKERS",
        flag: Some("workers"),
        value_name: "N",
        default: Fallback::Described("available cores"),
        help: "refinements running at once",
        parse: |v, c| {
            c.pool.workers = NonZeroUsize::new(number(v)? as usize).ok_or("must be at least 1")?;
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_QUEUE",
        flag: Some("queue"),
        value_name: "N",
        default: Fallback::Value("64"),
        help: "jobs that may wait when every worker is busy; beyond that 503",
        parse: |v, c| number(v).map(|n| c.pool.queue = n as usize),
    },
    Setting {
        name: "MESHFIT_MAX_VERTICES",
        flag: Some("max-vertices"),
        value_name: "N",
        default: Fallback::Value("2000000"),
        help: "largest `max_vertices` a request may ask for",
        parse: |v, c| {
            let n = number(v)?;
            if !(4..=crate::refine::MAX_VERTICES as u64).contains(&n) {
                return Err(format!("must be between 4 and {}", crate::refine::MAX_VERTICES));
            }
            c.limits.max_vertices = n as usize;
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_MAX_GRID_POINTS",
        flag: Some("max-grid-points"),
        value_name: "N",
        default: Fallback::Value("16785409"),
        help: "largest nx·ny of a grid (the default is 4097²), checked against a file's header before it is decoded",
        parse: |v, c| at_least(v, 4).map(|n| c.limits.max_grid_points = n as usize),
    },
    Setting {
        name: "MESHFIT_MAX_BODY_BYTES",
        flag: Some("max-body-bytes"),
        value_name: "BYTES",
        default: Fallback::Value("268435456"),
        help: "largest request body (a 4097×4097 grid at full precision needs about 350 MB)",
        parse: |v, c| at_least(v, 1024).map(|n| c.body.max_bytes = n as usize),
    },
    Setting {
        name: "MESHFIT_MAX_EXPRESSION_LEN",
        flag: Some("max-expression-len"),
        value_name: "N",
        default: Fallback::Value("4096"),
        help: "longest expression, in characters",
        parse: |v, c| at_least(v, 1).map(|n| c.limits.max_expression_len = n as usize),
    },
    Setting {
        name: "MESHFIT_JOB_TIME_LIMIT_MS",
        flag: Some("job-time-limit-ms"),
        value_name: "MS",
        default: Fallback::Value("60000"),
        help: "longest a job runs; caps `time_limit_ms`",
        parse: |v, c| millis(v, 1).map(|d| c.limits.job_time_limit = d),
    },
    Setting {
        name: "MESHFIT_MEMORY_BYTES",
        flag: Some("memory-bytes"),
        value_name: "BYTES",
        default: Fallback::Described("half the machine's memory, or the container's limit"),
        help: "the memory budget that request bodies, jobs and cached meshes are charged to before they are taken; past it, 503",
        parse: |v, c| {
            let n = at_least(v, 64 << 20).map_err(|_| "must be at least 67108864 (64 MiB)".to_owned())?;
            c.pool.memory_bytes = n;
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_CACHE_BYTES",
        flag: Some("cache-bytes"),
        value_name: "BYTES",
        default: Fallback::Value("1073741824"),
        help: "memory for finished meshes, part of the budget and at most half of it (a default larger than half shrinks to it)",
        parse: |v, c| number(v).map(|n| c.cache.memory_bytes = n),
    },
    Setting {
        name: "MESHFIT_CACHE_DIR",
        flag: Some("cache-dir"),
        value_name: "DIR",
        default: Fallback::Described("unset"),
        help: "also keep finished meshes here, across restarts",
        parse: |v, c| {
            c.cache.dir = (!v.is_empty()).then(|| PathBuf::from(v));
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_CACHE_DIR_BYTES",
        flag: Some("cache-dir-bytes"),
        value_name: "BYTES",
        default: Fallback::Value("10737418240"),
        help: "disk for those meshes; the least recently used file is deleted first",
        parse: |v, c| at_least(v, 1).map(|n| c.cache.dir_bytes = n),
    },
    Setting {
        name: "MESHFIT_SHUTDOWN_GRACE_MS",
        flag: Some("shutdown-grace-ms"),
        value_name: "MS",
        default: Fallback::Value("10000"),
        help: "after SIGTERM or Ctrl-C: time running jobs get before they are cancelled",
        parse: |v, c| millis(v, 0).map(|d| c.shutdown_grace = d),
    },
    Setting {
        name: "MESHFIT_MAX_CONNECTIONS",
        flag: Some("max-connections"),
        value_name: "N",
        default: Fallback::Described("the file limit less 256 (at most 10000)"),
        help: "connections served at once; past it, a connection gets a 503 and is closed",
        parse: |v, c| at_least(v, 1).map(|n| c.connections.max = n as usize),
    },
    Setting {
        name: "MESHFIT_HEADER_TIMEOUT_MS",
        flag: Some("header-timeout-ms"),
        value_name: "MS",
        default: Fallback::Value("15000"),
        help: "time to send a request's headers, counted from the end of the previous response: it also closes idle keep-alive connections",
        parse: |v, c| millis(v, 1).map(|d| c.connections.header_timeout = d),
    },
    Setting {
        name: "MESHFIT_BODY_TIMEOUT_MS",
        flag: Some("body-timeout-ms"),
        value_name: "MS",
        default: Fallback::Value("15000"),
        help: "longest pause in a request body; a body may also take no longer than this plus its length at 64 KiB/s; then 408",
        parse: |v, c| millis(v, 1).map(|d| c.body.timeout = d),
    },
    Setting {
        name: "MESHFIT_WRITE_TIMEOUT_MS",
        flag: Some("write-timeout-ms"),
        value_name: "MS",
        default: Fallback::Value("30000"),
        help: "longest a response may wait for its client to read; then the connection is closed and its buffers freed",
        parse: |v, c| millis(v, 1).map(|d| c.connections.write_timeout = d),
    },
    Setting {
        name: "MESHFIT_API_KEYS",
        flag: None,
        value_name: "KEYS",
        default: Fallback::Described("unset"),
        help: "comma-separated API keys (16 characters or more); with any, every /v1 route needs `Authorization: Bearer <key>`",
        parse: |v, c| add_keys(v.split(','), &mut c.callers.api_keys),
    },
    Setting {
        name: "MESHFIT_API_KEYS_FILE",
        flag: Some("api-keys-file"),
        value_name: "FILE",
        default: Fallback::Described("unset"),
        help: "a file of API keys, one per line (`#` comments); keys are never flags, which the process list would show",
        parse: |v, c| {
            let text = std::fs::read_to_string(v).map_err(|e| format!("cannot read the file: {e}"))?;
            add_keys(text.lines().filter(|l| !l.trim_start().starts_with('#')), &mut c.callers.api_keys)
        },
    },
    Setting {
        name: "MESHFIT_CORS_ORIGINS",
        flag: Some("cors-origins"),
        value_name: "ORIGINS",
        default: Fallback::Described("unset (CORS off)"),
        help: "comma-separated origins, `https://app.example`, whose pages may call the API; `*` for any",
        parse: |v, c| {
            let origin = |o: &str| is_origin(o).then(|| o.to_owned());
            c.callers.cors_origins =
                comma_separated(v, origin, "expected `*` or scheme://host[:port], comma-separated")?;
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_CLIENT_SHARE",
        flag: Some("client-share"),
        value_name: "FRACTION",
        default: Fallback::Value("0.5"),
        help: "one client's share of the jobs a server takes (workers plus queue), and of the workers it runs before others' waiting jobs go first (an idle worker takes any job); 1 for a single-tenant server",
        parse: |v, c| match v.parse::<f64>() {
            Ok(x) if x > 0.0 && x <= 1.0 => {
                c.pool.client_share = x;
                Ok(())
            }
            _ => Err("expected a number in (0, 1], e.g. 0.5".to_owned()),
        },
    },
    Setting {
        name: "MESHFIT_TRUSTED_PROXIES",
        flag: Some("trusted-proxies"),
        value_name: "RANGES",
        default: Fallback::Described("none"),
        help: "proxies (comma-separated addresses or CIDR ranges) whose `Forwarded` / `X-Forwarded-For` names the client",
        parse: |v, c| {
            let proxy = |p: &str| p.parse::<IpNet>().or_else(|_| p.parse::<IpAddr>().map(IpNet::from)).ok();
            c.callers.trusted_proxies = comma_separated(
                v,
                proxy,
                "expected addresses or CIDR ranges, comma-separated: 10.0.0.0/8, ::1",
            )?;
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_REDIS_URL",
        flag: Some("redis-url"),
        value_name: "URL",
        default: Fallback::Described("unset"),
        help: "share results and jobs with other replicas through this Redis (a password in it would show in the process list as a flag: give that one as the variable)",
        // TLS (rediss://) would need one of redis-rs's TLS features, which are not built.
        parse: |v, c| match redis::parse_redis_url(v).filter(|u| u.scheme() == "redis") {
            Some(_) => {
                c.redis.url = Some(v.to_owned());
                Ok(())
            }
            None => Err("expected redis://[user:password@]host[:port][/db]".to_owned()),
        },
    },
    Setting {
        name: "MESHFIT_REDIS_TTL_MS",
        flag: Some("redis-ttl-ms"),
        value_name: "MS",
        default: Fallback::Value("86400000"),
        help: "how long Redis keeps results, job postings and requests",
        parse: |v, c| millis(v, 1).map(|d| c.redis.ttl = d),
    },
    Setting {
        name: "MESHFIT_REDIS_MAX_BYTES",
        flag: Some("redis-max-bytes"),
        value_name: "BYTES",
        default: Fallback::Value("268435456"),
        help: "largest result or request kept in Redis; larger ones stay on their replica",
        parse: |v, c| number(v).map(|n| c.redis.max_bytes = n),
    },
    Setting {
        name: "MESHFIT_REDIS_LEASE_MS",
        flag: Some("redis-lease-ms"),
        value_name: "MS",
        default: Fallback::Value("10000"),
        help: "a job's lease: how soon another replica takes over the job of one that died",
        parse: |v, c| millis(v, 30).map(|d| c.redis.lease = d),
    },
    Setting {
        name: "MESHFIT_LOG_FORMAT",
        flag: Some("log-format"),
        value_name: "FORMAT",
        default: Fallback::Value("text"),
        help: "`json` for one JSON object per line",
        parse: |v, c| {
            c.log_format = match v {
                "text" => LogFormat::Text,
                "json" => LogFormat::Json,
                _ => return Err("expected text or json".to_owned()),
            };
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_LOG",
        flag: None,
        value_name: "FILTER",
        default: Fallback::Value("info"),
        help: "log filter, in `RUST_LOG` syntax",
        parse: |v, c| {
            tracing_subscriber::EnvFilter::try_new(v).map_err(|e| format!("not a log filter: {e}"))?;
            c.log_filter = v.to_owned();
            Ok(())
        },
    },
];

impl TryFrom<RawConfig> for Config {
    type Error = ConfigError;

    fn try_from(raw: RawConfig) -> Result<Self, ConfigError> {
        let mut config = Config::default();
        let mut problems = Vec::new();
        for (name, value) in &raw.values {
            let setting = Setting::named(name);
            let outcome = match setting {
                Some(setting) => (setting.parse)(value.trim(), &mut config),
                None => Err("unknown setting".to_owned()),
            };
            if let Err(why) = outcome {
                // A key, or a URL with a password, is a secret: name the variable, not its value.
                // A misspelt one (MESHFIT_API_KEY) may be a secret too: unknown values are not shown.
                let secret = setting.is_none_or(Setting::is_secret);
                let shown = if secret { "<hidden>".to_owned() } else { format!("{value:?}") };
                problems.push(problem(&raw, name, shown, why));
            }
        }
        // The cache is part of the budget; a default cache larger than half of it shrinks,
        // a configured one is an error.
        if config.cache.memory_bytes > config.pool.memory_bytes / 2 {
            if let Some(value) = raw.values.get("MESHFIT_CACHE_BYTES") {
                let why =
                    format!("must be at most half of MESHFIT_MEMORY_BYTES ({})", config.pool.memory_bytes);
                problems.push(problem(&raw, "MESHFIT_CACHE_BYTES", format!("{value:?}"), why));
            } else {
                config.cache.memory_bytes = config.pool.memory_bytes / 2;
            }
        }
        if problems.is_empty() { Ok(config) } else { Err(ConfigError(problems)) }
    }
}

/// A problem with variable `name`, under the flag that set it if one did.
fn problem(raw: &RawConfig, name: &str, shown: String, why: String) -> ConfigProblem {
    ConfigProblem { name: name.to_owned(), flag: raw.flags.get(name).copied(), shown, why }
}

/// `host:port` to listen on: an address (`0.0.0.0:8080`, `[::]:8080`) or a host name
/// (`localhost:8080`), resolved once here; the first address found is taken.
///
/// # Errors
/// When `v` is not `host:port` or its host does not resolve, saying what it takes.
pub fn listen_addr(v: &str) -> Result<SocketAddr, &'static str> {
    use std::net::ToSocketAddrs;
    const EXPECTED: &str = "expected host:port, e.g. 0.0.0.0:8080 or localhost:8080";
    if let Ok(addr) = v.parse() {
        return Ok(addr);
    }
    let (host, port) = v.rsplit_once(':').ok_or(EXPECTED)?;
    if host.is_empty() || port.parse::<u16>().is_err() {
        return Err(EXPECTED);
    }
    v.to_socket_addrs().ok().and_then(|mut addrs| addrs.next()).ok_or("the host name does not resolve")
}

/// Adds each non-blank key; every key must be long enough to be a secret.
fn add_keys<'a>(keys: impl Iterator<Item = &'a str>, into: &mut ApiKeys) -> Result<(), String> {
    for key in keys.map(str::trim).filter(|k| !k.is_empty()) {
        if key.len() < MIN_KEY_LEN || key.contains(char::is_whitespace) {
            return Err(format!("each key must be at least {MIN_KEY_LEN} characters, with no spaces"));
        }
        into.insert(key);
    }
    Ok(())
}

/// `*`, or `http(s)://host[:port]` with no path, as browsers send in `Origin`.
fn is_origin(o: &str) -> bool {
    let rest = o.strip_prefix("https://").or_else(|| o.strip_prefix("http://"));
    o == "*" || rest.is_some_and(|host| !host.is_empty() && !host.contains(['/', ' ', ',']))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(pairs: &[(&str, &str)]) -> RawConfig {
        let mut raw = RawConfig::default();
        for (k, v) in pairs {
            raw.set(k, *v);
        }
        raw
    }

    #[test]
    fn no_variables_give_the_documented_defaults() {
        let c = Config::try_from(RawConfig::default()).unwrap();
        assert_eq!(c.addr.to_string(), "0.0.0.0:8080");
        assert_eq!(
            (c.pool.queue, c.limits.max_vertices, c.limits.max_grid_points),
            (64, 2_000_000, 4097 * 4097)
        );
        assert_eq!((c.cache.dir, c.cache.dir_bytes), (None, 10 << 30));
    }

    #[test]
    fn variables_override_defaults() {
        let c = Config::try_from(raw(&[
            ("MESHFIT_ADDR", "127.0.0.1:9000"),
            ("MESHFIT_WORKERS", "3"),
            ("MESHFIT_MAX_VERTICES", "1_000"),
            ("MESHFIT_CACHE_DIR", "/tmp/x"),
            ("MESHFIT_CACHE_DIR_BYTES", "1_000_000"),
            ("MESHFIT_LOG_FORMAT", "json"),
        ]))
        .unwrap();
        assert_eq!(c.addr.port(), 9000);
        assert_eq!((c.pool.workers.get(), c.limits.max_vertices), (3, 1000));
        assert_eq!((c.cache.dir, c.cache.dir_bytes), (Some(PathBuf::from("/tmp/x")), 1_000_000));
        assert_eq!(c.log_format, LogFormat::Json);
    }

    #[test]
    fn redis_settings_are_read_and_a_bad_url_is_reported_without_its_password() {
        let c = Config::try_from(raw(&[
            ("MESHFIT_REDIS_URL", "redis://cache:6380/2"),
            ("MESHFIT_REDIS_LEASE_MS", "2500"),
            ("MESHFIT_REDIS_MAX_BYTES", "1_000"),
        ]))
        .unwrap();
        assert_eq!(c.redis.url.as_deref(), Some("redis://cache:6380/2"));
        assert_eq!((c.redis.lease, c.redis.max_bytes), (Duration::from_millis(2500), 1000));
        assert_eq!(Config::try_from(RawConfig::default()).unwrap().redis.url, None, "alone by default");
        let err = Config::try_from(raw(&[
            ("MESHFIT_REDIS_URL", "http://user:s3cret@cache:6379"),
            ("MESHFIT_REDIS_LEASE_MS", "5"),
        ]))
        .unwrap_err();
        assert_eq!(err.0.len(), 2, "{err}");
        assert!(err.0.iter().any(|p| p.to_string().starts_with("MESHFIT_REDIS_URL=<hidden>")), "{err}");
        assert!(!err.to_string().contains("s3cret"), "{err}");
    }

    #[test]
    fn every_bad_setting_is_reported_at_once_with_its_name_and_value() {
        let err = Config::try_from(raw(&[
            ("MESHFIT_WORKERS", "0"),
            ("MESHFIT_ADDR", "localhost"),
            ("MESHFIT_QEUE", "3"),
            ("MESHFIT_CACHE_DIR_BYTES", "0"),
        ]))
        .unwrap_err();
        assert_eq!(err.0.len(), 4, "{err}");
        assert!(err.0.iter().any(|p| p.to_string().starts_with("MESHFIT_WORKERS=\"0\"")), "{err}");
        assert!(err.0.iter().any(|p| p.name == "MESHFIT_QEUE" && p.why == "unknown setting"), "{err}");
        // A misspelt variable may hold a key: its value is not echoed.
        let err = Config::try_from(raw(&[("MESHFIT_API_KEY", "secret-0123456789abcdef")])).unwrap_err();
        assert_eq!(err.to_string(), "invalid configuration:\n  MESHFIT_API_KEY=<hidden>: unknown setting");
    }

    #[test]
    fn the_log_filter_is_a_setting_checked_with_the_others() {
        let c = Config::try_from(raw(&[("MESHFIT_LOG", "meshfit=debug,tower_http=warn")])).unwrap();
        assert_eq!(c.log_filter, "meshfit=debug,tower_http=warn");
        assert_eq!(Config::try_from(raw(&[])).unwrap().log_filter, "info");
        let err = Config::try_from(raw(&[("MESHFIT_LOG", "meshfit=loud")])).unwrap_err();
        assert!(err.0[0].name == "MESHFIT_LOG" && err.0[0].why.starts_with("not a log filter"), "{err}");
    }

    #[test]
    fn the_address_may_name_a_host_and_a_bad_one_says_what_it_takes() {
        let c = Config::try_from(raw(&[("MESHFIT_ADDR", "localhost:9001")])).unwrap();
        assert!(c.addr.ip().is_loopback() && c.addr.port() == 9001, "{}", c.addr);
        let c = Config::try_from(raw(&[("MESHFIT_ADDR", "[::1]:9002")])).unwrap();
        assert_eq!(c.addr.to_string(), "[::1]:9002");
        for bad in ["localhost", ":8080", "localhost:http", "localhost:99999"] {
            let err = Config::try_from(raw(&[("MESHFIT_ADDR", bad)])).unwrap_err();
            assert!(err.0[0].why.contains("localhost:8080"), "{bad}: {err}");
        }
    }

    #[test]
    fn a_setting_given_as_a_flag_is_reported_under_the_flag() {
        let mut r = raw(&[("MESHFIT_QUEUE", "many")]);
        let workers = Setting::named("MESHFIT_WORKERS").unwrap();
        r.set_from_flag(workers, "0");
        let err = Config::try_from(r).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("--workers \"0\" (MESHFIT_WORKERS): must be at least 1"), "{text}");
        assert!(text.contains("MESHFIT_QUEUE=\"many\": expected a whole number"), "{text}");
        // The environment's value, replaced by a later `set`, is no longer the flag's.
        let mut r = RawConfig::default();
        r.set_from_flag(workers, "0");
        r.set("MESHFIT_WORKERS", "0");
        assert_eq!(Config::try_from(r).unwrap_err().0[0].flag, None);
    }

    #[test]
    fn each_default_written_in_the_table_is_the_one_the_code_uses() {
        let defaults = Config::default();
        for setting in SETTINGS {
            if let Fallback::Value(v) = setting.default {
                let mut config = defaults.clone();
                (setting.parse)(v, &mut config).unwrap_or_else(|e| panic!("{}: {e}", setting.name));
                assert_eq!(config, defaults, "{} documents {v}", setting.name);
            }
        }
    }

    #[test]
    fn each_parser_sets_its_own_setting() {
        // A value other than the default, per setting, that its parser takes.
        let other = |name: &str| match name {
            "MESHFIT_ADDR" => "127.0.0.1:9",
            "MESHFIT_CLIENT_SHARE" => "0.25",
            "MESHFIT_CACHE_DIR" => "/tmp/meshfit-cache",
            "MESHFIT_CORS_ORIGINS" => "https://app.example",
            "MESHFIT_TRUSTED_PROXIES" => "10.0.0.0/8",
            "MESHFIT_REDIS_URL" => "redis://cache:6379",
            "MESHFIT_LOG_FORMAT" => "json",
            "MESHFIT_API_KEYS" => "key-0123456789abcdef",
            "MESHFIT_MEMORY_BYTES" => "68719476736",
            _ => "12345",
        };
        let defaults = Config::default();
        // Read by the log subscriber, or by a file: not in Config's fields this way.
        for setting in SETTINGS.iter().filter(|s| !matches!(s.name, "MESHFIT_LOG" | "MESHFIT_API_KEYS_FILE"))
        {
            let mut config = defaults.clone();
            (setting.parse)(other(setting.name), &mut config)
                .unwrap_or_else(|e| panic!("{}: {e}", setting.name));
            assert_ne!(config, defaults, "{} changed nothing", setting.name);
        }
    }

    #[test]
    fn names_and_flags_are_unique_and_every_flag_is_its_variables_name() {
        let mut names: Vec<&str> = SETTINGS.iter().map(|s| s.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), SETTINGS.len());
        for s in SETTINGS {
            if let Some(flag) = s.flag {
                let from_name = s.name.trim_start_matches("MESHFIT_").to_lowercase().replace('_', "-");
                assert_eq!(flag, from_name, "{}", s.name);
            }
        }
    }

    #[test]
    fn the_readmes_table_is_the_settings_table() {
        let readme =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/settings.md")).unwrap();
        let rows: Vec<&str> = readme.lines().filter(|l| l.starts_with("| `MESHFIT_")).collect();
        let expected: Vec<String> = SETTINGS
            .iter()
            .map(|s| {
                let default = match s.default {
                    Fallback::Value(v) => format!("`{v}`"),
                    Fallback::Described(d) => d.to_owned(),
                };
                format!("| `{}` | {default} | {} |", s.name, s.help)
            })
            .collect();
        assert_eq!(rows, expected, "the README's table of settings differs from config::SETTINGS");
    }

    #[test]
    fn keys_origins_and_shares_are_checked_and_keys_never_printed() {
        let dir = std::env::temp_dir().join(format!("meshfit-keys-{}", std::process::id()));
        std::fs::write(&dir, "# operators\nfile-key-0123456789abcdef\n\n").unwrap();
        let c = Config::try_from(raw(&[
            ("MESHFIT_API_KEYS", "env-key-0123456789abcdef, other-key-0123456789ab"),
            ("MESHFIT_API_KEYS_FILE", dir.to_str().unwrap()),
            ("MESHFIT_CORS_ORIGINS", "https://app.example, http://localhost:3000"),
            ("MESHFIT_CLIENT_SHARE", "0.25"),
            ("MESHFIT_TRUSTED_PROXIES", "10.0.0.0/8, 172.17.0.1"),
        ]))
        .unwrap();
        let proxies: Vec<String> = c.callers.trusted_proxies.iter().map(ToString::to_string).collect();
        assert_eq!(proxies, ["10.0.0.0/8", "172.17.0.1/32"]);
        std::fs::remove_file(&dir).unwrap();
        assert_eq!(c.callers.api_keys.len(), 3);
        assert_eq!(c.callers.cors_origins, ["https://app.example", "http://localhost:3000"]);
        assert_eq!(c.pool.client_share, 0.25);
        assert!(!format!("{c:?}").contains("env-key"));
        let err = Config::try_from(raw(&[
            ("MESHFIT_API_KEYS", "short"),
            ("MESHFIT_API_KEYS_FILE", "/no/such/file"),
            ("MESHFIT_CORS_ORIGINS", "app.example/path"),
            ("MESHFIT_CLIENT_SHARE", "0"),
            ("MESHFIT_TRUSTED_PROXIES", "nginx"),
        ]))
        .unwrap_err();
        assert_eq!(err.0.len(), 5, "{err}");
        assert!(!err.to_string().contains("short\""), "a bad key is not echoed: {err}");
    }
}
