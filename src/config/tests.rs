//! Tests of the settings: defaults, every bad value at once, the table of the docs.

use super::*;
use std::path::PathBuf;
use std::time::Duration;

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
    assert_eq!(c.addr.to_string(), "127.0.0.1:8080");
    assert_eq!((c.pool.queue, c.limits.max_vertices, c.limits.max_grid_points), (64, 2_000_000, 4097 * 4097));
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
        "MESHFIT_DATASET" => "alps=/data/alps.tif",
        "MESHFIT_TILE_ERROR_FACTOR" => "0.5",
        _ => "12345",
    };
    let defaults = Config::default();
    // Read by the log subscriber, or by a file: not in Config's fields this way.
    for setting in SETTINGS.iter().filter(|s| !matches!(s.name, "MESHFIT_LOG" | "MESHFIT_API_KEYS_FILE")) {
        let mut config = defaults.clone();
        (setting.parse)(other(setting.name), &mut config).unwrap_or_else(|e| panic!("{}: {e}", setting.name));
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
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/settings.md")).unwrap();
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
