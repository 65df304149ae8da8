//! Service settings: environment variables (`MESHFIT_*`) over safe defaults, validated once.
//!
//! Two stages, as ripgrep's LowArgs/HiArgs: [`RawConfig`] holds the strings as given,
//! [`Config`] the typed values. Nothing downstream parses a string. Each setting is declared
//! once, in [`SETTINGS`]: its variable, flag, default, help and parser; `meshfit serve`'s flags
//! and `--help` are made from it, and tests hold the README's table and the defaults to it.

mod groups;
mod raw;
mod settings;
#[cfg(test)]
mod tests;

pub use groups::{
    ApiKeys, BodyLimits, Callers, Config, Connections, DEFAULT_ADDR, LogFormat, MIN_KEY_LEN, Redis,
    default_max_connections,
};
pub use raw::{ConfigError, ConfigProblem, RawConfig};
pub use settings::{Fallback, SETTINGS, Setting, listen_addr};
