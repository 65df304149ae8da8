//! Service settings: environment variables (`MESHFIT_*`) over safe defaults, validated once.
//!
//! Two stages, as ripgrep's LowArgs/HiArgs: [`RawConfig`] holds the strings as given,
//! [`Config`] the typed values. Nothing downstream parses a string.

use crate::http::access::{ApiKeys, MIN_KEY_LEN};
use ipnet::IpNet;
use std::collections::BTreeMap;
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

/// Validated service settings. Every field has a default; see the README's table.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Where to listen (`MESHFIT_ADDR`, default 0.0.0.0:8080).
    pub addr: SocketAddr,
    /// Refinements running at once (`MESHFIT_WORKERS`, default: available cores).
    pub workers: NonZeroUsize,
    /// Jobs that may wait for a worker (`MESHFIT_QUEUE`, default 64); more get 503.
    pub queue: usize,
    /// Largest `max_vertices` a request may ask for (`MESHFIT_MAX_VERTICES`, default 2,000,000).
    pub max_vertices: usize,
    /// Largest nx·ny of a grid (`MESHFIT_MAX_GRID_POINTS`, default 16,785,409: 4097 × 4097).
    pub max_grid_points: usize,
    /// Largest request body (`MESHFIT_MAX_BODY_BYTES`, default 256 MiB: a 4097 × 4097 grid
    /// written with up to 14 characters per value; raise it for full-precision grids).
    pub max_body_bytes: usize,
    /// Longest expression in characters (`MESHFIT_MAX_EXPRESSION_LEN`, default 4096).
    pub max_expression_len: usize,
    /// Longest a job may run (`MESHFIT_JOB_TIME_LIMIT_MS`, default 60 s); caps `time_limit_ms`.
    pub job_time_limit: Duration,
    /// The memory budget (`MESHFIT_MEMORY_BYTES`, default half the machine's or the
    /// container's memory): request bodies, jobs (by their vertex budgets) and cached meshes
    /// are charged to it before they are taken; past it, 503.
    pub memory_bytes: u64,
    /// Memory for finished meshes (`MESHFIT_CACHE_BYTES`, default 1 GiB, and at most half
    /// the memory budget); part of the budget.
    pub cache_bytes: u64,
    /// Where finished meshes are also written, to survive restarts (`MESHFIT_CACHE_DIR`, unset).
    pub cache_dir: Option<PathBuf>,
    /// Disk for those files, least recently used deleted first (`MESHFIT_CACHE_DIR_BYTES`,
    /// default 10 GiB).
    pub cache_dir_bytes: u64,
    /// How long running jobs may finish after SIGTERM before they are cancelled
    /// (`MESHFIT_SHUTDOWN_GRACE_MS`, default 10 s).
    pub shutdown_grace: Duration,
    /// `MESHFIT_LOG_FORMAT`: `text` (default) or `json`.
    pub log_format: LogFormat,
    /// Connections served at once (`MESHFIT_MAX_CONNECTIONS`, default: the file limit less
    /// 256, at most 10,000); past it, a connection gets a 503 and is closed.
    pub max_connections: usize,
    /// Time from the end of a response, or a connection's start, to the end of the next
    /// request's headers (`MESHFIT_HEADER_TIMEOUT_MS`, default 15 s): it closes idle
    /// keep-alive connections and slow headers.
    pub header_timeout: Duration,
    /// Longest wait for the next part of a request body (`MESHFIT_BODY_TIMEOUT_MS`, default
    /// 15 s); past it, 408.
    pub body_timeout: Duration,
    /// Longest a response may wait for the client to read (`MESHFIT_WRITE_TIMEOUT_MS`,
    /// default 30 s); past it, the connection is closed.
    pub write_timeout: Duration,
    /// API keys (`MESHFIT_API_KEYS`, comma-separated, and `MESHFIT_API_KEYS_FILE`, one per
    /// line); with any, every `/v1` route needs `Authorization: Bearer <key>`. Default none.
    pub api_keys: ApiKeys,
    /// Origins whose web pages may call the API (`MESHFIT_CORS_ORIGINS`, comma-separated
    /// `scheme://host[:port]`, or `*`). Default none: CORS is off.
    pub cors_origins: Vec<String>,
    /// One client's (key's, or address's without keys) share of the jobs the server takes,
    /// running and queued, and of the workers it runs before other clients' waiting jobs go
    /// first; an idle worker takes any waiting job (`MESHFIT_CLIENT_SHARE`, in (0, 1],
    /// default 0.5).
    pub client_share: f64,
    /// Proxies whose `Forwarded` or `X-Forwarded-For` header names the client, for shares
    /// without keys (`MESHFIT_TRUSTED_PROXIES`, comma-separated addresses or CIDR ranges).
    /// Default none: a client is the address that connects.
    pub trusted_proxies: Vec<IpNet>,
    /// Replicas share results and jobs through this Redis (`MESHFIT_REDIS_URL`,
    /// `redis://host:port/db`; unset: this process serves alone), with the settings below.
    pub redis_url: Option<String>,
    /// How long Redis keeps results, records and requests (`MESHFIT_REDIS_TTL_MS`, default a
    /// day).
    pub redis_ttl: Duration,
    /// The largest result (compact form) or request body kept in Redis
    /// (`MESHFIT_REDIS_MAX_BYTES`, default 256 MiB, a mesh of about 3·10^6 vertices); larger ones stay on their replica.
    pub redis_max_bytes: u64,
    /// A job's lease (`MESHFIT_REDIS_LEASE_MS`, default 10 s): how long after its replica
    /// dies another takes it over.
    pub redis_lease: Duration,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            addr: DEFAULT_ADDR,
            workers: std::thread::available_parallelism().unwrap_or(NonZeroUsize::MIN),
            queue: 64,
            max_vertices: 2_000_000,
            // 4097 × 4097: the largest grid of the README's benchmarks, and of many DEM tiles.
            max_grid_points: 4097 * 4097,
            max_body_bytes: 256 << 20,
            max_expression_len: 4096,
            job_time_limit: Duration::from_secs(60),
            memory_bytes: crate::jobs::default_memory_bytes(),
            cache_bytes: 1 << 30,
            cache_dir: None,
            cache_dir_bytes: 10 << 30,
            shutdown_grace: Duration::from_secs(10),
            log_format: LogFormat::Text,
            max_connections: crate::http::conn::default_max_connections(),
            header_timeout: Duration::from_secs(15),
            body_timeout: Duration::from_secs(15),
            write_timeout: Duration::from_secs(30),
            api_keys: ApiKeys::default(),
            cors_origins: Vec::new(),
            client_share: 0.5,
            trusted_proxies: Vec::new(),
            redis_url: None,
            redis_ttl: Duration::from_secs(24 * 3600),
            redis_max_bytes: 256 << 20,
            redis_lease: Duration::from_secs(10),
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

    /// Sets one variable from the command-line flag `flag` (flags override the environment),
    /// so that a bad value is reported under the flag the user typed.
    pub fn set_from_flag(&mut self, name: &str, flag: &'static str, value: impl Into<String>) {
        self.set(name, value);
        self.flags.insert(name.to_owned(), flag);
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
    /// The flag it was given with, e.g. `--workers`, if it was.
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
            Some(flag) => write!(f, "{flag} {shown} ({name}): {why}"),
            None => write!(f, "{name}={shown}: {why}"),
        }
    }
}

/// Every invalid setting, each naming its variable (or flag) and value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid configuration:\n  {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n  "))]
pub struct ConfigError(pub Vec<ConfigProblem>);

impl TryFrom<RawConfig> for Config {
    type Error = ConfigError;

    fn try_from(raw: RawConfig) -> Result<Self, ConfigError> {
        let mut config = Config::default();
        let mut problems = Vec::new();
        for (name, value) in &raw.values {
            let v = value.trim();
            let number = || v.replace('_', "").parse::<u64>().map_err(|_| "expected a whole number");
            let millis = || {
                number().and_then(|n| (n >= 1).then(|| Duration::from_millis(n)).ok_or("must be at least 1"))
            };
            let outcome: Result<(), &str> = match name.as_str() {
                "MESHFIT_ADDR" => listen_addr(v).map(|a| config.addr = a),
                "MESHFIT_WORKERS" => number().and_then(|n| {
                    NonZeroUsize::new(n as usize).map(|n| config.workers = n).ok_or("must be at least 1")
                }),
                "MESHFIT_QUEUE" => number().map(|n| config.queue = n as usize),
                "MESHFIT_MAX_VERTICES" => number().and_then(|n| {
                    (4..=crate::refine::MAX_VERTICES as u64)
                        .contains(&n)
                        .then(|| config.max_vertices = n as usize)
                        .ok_or("must be between 4 and 400000000")
                }),
                "MESHFIT_MAX_GRID_POINTS" => number().and_then(|n| {
                    (n >= 4).then(|| config.max_grid_points = n as usize).ok_or("must be at least 4")
                }),
                "MESHFIT_MAX_BODY_BYTES" => number().and_then(|n| {
                    (n >= 1024).then(|| config.max_body_bytes = n as usize).ok_or("must be at least 1024")
                }),
                "MESHFIT_MAX_EXPRESSION_LEN" => number().and_then(|n| {
                    (n >= 1).then(|| config.max_expression_len = n as usize).ok_or("must be at least 1")
                }),
                "MESHFIT_JOB_TIME_LIMIT_MS" => millis().map(|d| config.job_time_limit = d),
                "MESHFIT_CACHE_BYTES" => number().map(|n| config.cache_bytes = n),
                "MESHFIT_MEMORY_BYTES" => number().and_then(|n| {
                    (n >= 64 << 20)
                        .then(|| config.memory_bytes = n)
                        .ok_or("must be at least 67108864 (64 MiB)")
                }),
                "MESHFIT_CACHE_DIR" => {
                    config.cache_dir = (!v.is_empty()).then(|| PathBuf::from(v));
                    Ok(())
                }
                "MESHFIT_CACHE_DIR_BYTES" => number()
                    .and_then(|n| (n >= 1).then(|| config.cache_dir_bytes = n).ok_or("must be at least 1")),
                "MESHFIT_SHUTDOWN_GRACE_MS" => {
                    number().map(|n| config.shutdown_grace = Duration::from_millis(n))
                }
                "MESHFIT_LOG_FORMAT" => match v {
                    "text" => Ok(LogFormat::Text),
                    "json" => Ok(LogFormat::Json),
                    _ => Err("expected text or json"),
                }
                .map(|f| config.log_format = f),
                "MESHFIT_MAX_CONNECTIONS" => number().and_then(|n| {
                    (n >= 1).then(|| config.max_connections = n as usize).ok_or("must be at least 1")
                }),
                "MESHFIT_HEADER_TIMEOUT_MS" => millis().map(|d| config.header_timeout = d),
                "MESHFIT_BODY_TIMEOUT_MS" => millis().map(|d| config.body_timeout = d),
                "MESHFIT_WRITE_TIMEOUT_MS" => millis().map(|d| config.write_timeout = d),
                "MESHFIT_API_KEYS" => add_keys(v.split(','), &mut config.api_keys),
                "MESHFIT_API_KEYS_FILE" => match std::fs::read_to_string(v) {
                    Ok(text) => add_keys(
                        text.lines().filter(|l| !l.trim_start().starts_with('#')),
                        &mut config.api_keys,
                    ),
                    Err(e) => {
                        let why = format!("cannot read the file: {e}");
                        problems.push(problem(&raw, name, format!("{value:?}"), why));
                        Ok(())
                    }
                },
                "MESHFIT_CORS_ORIGINS" => v
                    .split(',')
                    .map(str::trim)
                    .filter(|o| !o.is_empty())
                    .map(|o| {
                        is_origin(o)
                            .then(|| o.to_owned())
                            .ok_or("expected `*` or scheme://host[:port], comma-separated")
                    })
                    .collect::<Result<_, _>>()
                    .map(|origins| config.cors_origins = origins),
                "MESHFIT_CLIENT_SHARE" => match v.parse::<f64>() {
                    Ok(x) if x > 0.0 && x <= 1.0 => {
                        config.client_share = x;
                        Ok(())
                    }
                    _ => Err("expected a number in (0, 1], e.g. 0.5"),
                },
                "MESHFIT_TRUSTED_PROXIES" => v
                    .split(',')
                    .map(str::trim)
                    .filter(|p| !p.is_empty())
                    .map(|p| {
                        p.parse::<IpNet>().or_else(|_| p.parse::<IpAddr>().map(IpNet::from)).map_err(
                            |_| "expected addresses or CIDR ranges, comma-separated: 10.0.0.0/8, ::1",
                        )
                    })
                    .collect::<Result<_, _>>()
                    .map(|proxies| config.trusted_proxies = proxies),
                // TLS (rediss://) would need one of redis-rs's TLS features, which are not built.
                "MESHFIT_REDIS_URL" => match redis::parse_redis_url(v).filter(|u| u.scheme() == "redis") {
                    Some(_) => {
                        config.redis_url = Some(v.to_owned());
                        Ok(())
                    }
                    None => Err("expected redis://[user:password@]host[:port][/db]"),
                },
                "MESHFIT_REDIS_TTL_MS" => millis().map(|d| config.redis_ttl = d),
                "MESHFIT_REDIS_MAX_BYTES" => number().map(|n| config.redis_max_bytes = n),
                "MESHFIT_REDIS_LEASE_MS" => millis().and_then(|d| {
                    (d >= Duration::from_millis(30))
                        .then(|| config.redis_lease = d)
                        .ok_or("must be at least 30")
                }),
                // RUST_LOG-style filtering is read by the tracing subscriber itself.
                "MESHFIT_LOG" => Ok(()),
                _ => Err("unknown setting"),
            };
            if let Err(why) = outcome {
                // A key, or a URL with a password, is a secret: name the variable, not its value.
                let secret = matches!(name.as_str(), "MESHFIT_API_KEYS" | "MESHFIT_REDIS_URL");
                let shown = if secret { "<hidden>".to_owned() } else { format!("{value:?}") };
                problems.push(problem(&raw, name, shown, why.to_owned()));
            }
        }
        // The cache is part of the budget; a default cache larger than half of it shrinks,
        // a configured one is an error.
        if config.cache_bytes > config.memory_bytes / 2 {
            if let Some(value) = raw.values.get("MESHFIT_CACHE_BYTES") {
                let why = format!("must be at most half of MESHFIT_MEMORY_BYTES ({})", config.memory_bytes);
                problems.push(problem(&raw, "MESHFIT_CACHE_BYTES", format!("{value:?}"), why));
            } else {
                config.cache_bytes = config.memory_bytes / 2;
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
fn add_keys<'a>(keys: impl Iterator<Item = &'a str>, into: &mut ApiKeys) -> Result<(), &'static str> {
    for key in keys.map(str::trim).filter(|k| !k.is_empty()) {
        if key.len() < MIN_KEY_LEN || key.contains(char::is_whitespace) {
            return Err("each key must be at least 16 characters, with no spaces");
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
        assert_eq!((c.queue, c.max_vertices, c.max_grid_points), (64, 2_000_000, 4097 * 4097));
        assert_eq!((c.cache_dir, c.cache_dir_bytes), (None, 10 << 30));
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
        assert_eq!((c.workers.get(), c.max_vertices), (3, 1000));
        assert_eq!((c.cache_dir, c.cache_dir_bytes), (Some(PathBuf::from("/tmp/x")), 1_000_000));
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
        assert_eq!(c.redis_url.as_deref(), Some("redis://cache:6380/2"));
        assert_eq!((c.redis_lease, c.redis_max_bytes), (Duration::from_millis(2500), 1000));
        assert_eq!(Config::try_from(RawConfig::default()).unwrap().redis_url, None, "alone by default");
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
        r.set_from_flag("MESHFIT_WORKERS", "--workers", "0");
        let err = Config::try_from(r).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("--workers \"0\" (MESHFIT_WORKERS): must be at least 1"), "{text}");
        assert!(text.contains("MESHFIT_QUEUE=\"many\": expected a whole number"), "{text}");
        // The environment's value, replaced by a later `set`, is no longer the flag's.
        let mut r = RawConfig::default();
        r.set_from_flag("MESHFIT_WORKERS", "--workers", "0");
        r.set("MESHFIT_WORKERS", "0");
        assert_eq!(Config::try_from(r).unwrap_err().0[0].flag, None);
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
        let proxies: Vec<String> = c.trusted_proxies.iter().map(ToString::to_string).collect();
        assert_eq!(proxies, ["10.0.0.0/8", "172.17.0.1/32"]);
        std::fs::remove_file(&dir).unwrap();
        assert_eq!(c.api_keys.len(), 3);
        assert_eq!(c.cors_origins, ["https://app.example", "http://localhost:3000"]);
        assert_eq!(c.client_share, 0.25);
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
