//! Logging: `tracing` to stderr, as text or JSON lines, filtered as `MESHFIT_LOG` says
//! (RUST_LOG syntax, default `info`).

use crate::config::Config;
use std::io::IsTerminal;
use tracing_subscriber::EnvFilter;

/// Installs the global subscriber for `config`'s format and filter; a second call is ignored.
pub fn init(config: &Config) {
    // The filter was checked with the rest of the settings.
    let filter = EnvFilter::try_new(&config.log_filter).unwrap_or_else(|_| EnvFilter::new("info"));
    let ansi = std::io::stderr().is_terminal();
    let builder =
        tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).with_ansi(ansi);
    let _ = match config.log_format {
        crate::config::LogFormat::Text => builder.try_init(),
        crate::config::LogFormat::Json => {
            builder.json().flatten_event(true).with_current_span(true).with_span_list(false).try_init()
        }
    };
}
