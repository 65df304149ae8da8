//! [`SETTINGS`]: every setting, declared once, with its variable, flag, default, help and
//! parser.

use super::groups::{ApiKeys, Config, LogFormat, MIN_KEY_LEN};
use ipnet::IpNet;
use std::net::{IpAddr, SocketAddr};
use std::num::NonZeroUsize;
use std::path::PathBuf;
use std::time::Duration;

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
    pub(super) parse: fn(&str, &mut Config) -> Result<(), String>,
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

    /// Whether the value is a comma-separated list, whose flag may also be given once per item.
    pub fn is_list(&self) -> bool {
        matches!(self.name, "MESHFIT_DATASET" | "MESHFIT_CORS_ORIGINS" | "MESHFIT_TRUSTED_PROXIES")
    }

    /// Whether the value is a secret: a bad one is reported by name, never echoed.
    pub(super) fn is_secret(&self) -> bool {
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
        default: Fallback::Value("127.0.0.1:8080"),
        help: "listen address: `host:port`, an address or a host name (`localhost:8080`); the default serves this machine only, the container's `0.0.0.0:8080` every interface",
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
        name: "MESHFIT_JOB_RETENTION_MS",
        flag: Some("job-retention-ms"),
        value_name: "MS",
        default: Fallback::Value("86400000"),
        help: "how long `GET /v1/jobs` lists a submitted job (at most 10,000 of them); a job's own record, `GET /v1/jobs/{id}`, stays for the latest 10,000 finished",
        parse: |v, c| millis(v, 1).map(|d| c.pool.job_retention = d),
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
        help: "largest result or job spec kept in Redis; larger ones stay on their replica",
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
        name: "MESHFIT_DATASET",
        flag: Some("dataset"),
        value_name: "NAME=PATH",
        default: Fallback::Described("none"),
        help: "GeoTIFF DEMs (EPSG:4326) to serve terrain tiles of, each under its name: `NAME=PATH`, comma-separated, or the flag given once for each",
        parse: |v, c| {
            let named = |item: &str| {
                let (name, path) = item.split_once('=')?;
                is_dataset_name(name.trim()).then(|| (name.trim().to_owned(), PathBuf::from(path.trim())))
            };
            let files = comma_separated(
                v,
                named,
                "expected NAME=PATH, comma-separated; a name is 1 to 64 letters, digits, `-` or `_`, not 64 hex digits",
            )?;
            let mut names: Vec<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
            names.sort_unstable();
            if let Some(twice) = names.windows(2).find(|w| w[0] == w[1]) {
                return Err(format!("the name `{}` is given twice", twice[0]));
            }
            c.datasets.files = files;
            Ok(())
        },
    },
    Setting {
        name: "MESHFIT_DATASET_BYTES",
        flag: Some("dataset-bytes"),
        value_name: "BYTES",
        default: Fallback::Value("1073741824"),
        help: "memory uploaded datasets may hold: their files and a 64 MiB cache of decoded blocks each; past it, 507 until one is deleted",
        parse: |v, c| number(v).map(|n| c.datasets.max_bytes = n),
    },
    Setting {
        name: "MESHFIT_TILE_ERROR_FACTOR",
        flag: Some("tile-error-factor"),
        value_name: "FRACTION",
        default: Fallback::Value("1"),
        help: "each terrain tile of level z keeps within this times Cesium's 77,067.34 m / 2^z of its DEM; smaller is finer",
        parse: |v, c| match v.parse::<f64>() {
            Ok(x) if x > 0.0 && x <= 1.0 => {
                c.datasets.error_factor = x;
                Ok(())
            }
            _ => Err("expected a number in (0, 1], e.g. 0.5".to_owned()),
        },
    },
    Setting {
        name: "MESHFIT_TILE_CACHE_BYTES",
        flag: Some("tile-cache-bytes"),
        value_name: "BYTES",
        default: Fallback::Value("268435456"),
        help: "memory for terrain tiles made (gzipped), part of the memory budget",
        parse: |v, c| number(v).map(|n| c.datasets.tile_cache_bytes = n),
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

/// Whether `name` may name a dataset: it goes into URLs, and is never taken for an uploaded
/// dataset's id (64 hex digits).
fn is_dataset_name(name: &str) -> bool {
    let hex = name.len() == 64 && name.bytes().all(|b| b.is_ascii_hexdigit());
    (1..=64).contains(&name.len())
        && !hex
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
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
