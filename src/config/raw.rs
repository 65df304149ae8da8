//! The settings as given ([`RawConfig`]: strings by variable name), and their checking into a
//! [`Config`], every problem at once.

use super::groups::Config;
use super::settings::Setting;
use std::collections::BTreeMap;

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
