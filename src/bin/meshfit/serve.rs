//! `meshfit serve` (the default): the settings from the environment and the flags, logging,
//! the runtime, and the server until Ctrl-C or SIGTERM.

use super::output::Bytes;
use anyhow::{Context, Result};
use meshfit::config::{Config, RawConfig, SETTINGS, Setting};
use std::net::SocketAddr;

/// `meshfit serve`'s flags: one for each of [`SETTINGS`] that has one, which sets its
/// variable over the environment's.
#[derive(Default)]
pub(crate) struct ServeArgs {
    /// The settings given as flags, with their values.
    given: Vec<(&'static Setting, String)>,
}

impl clap::FromArgMatches for ServeArgs {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        // A list's flag given more than once is the list its variable writes: `--dataset a=x
        // --dataset b=y` is `MESHFIT_DATASET=a=x,b=y`.
        let given = SETTINGS
            .iter()
            .filter_map(|s| {
                let values: Vec<&String> = matches.get_many::<String>(s.flag?)?.collect();
                Some((s, values.iter().map(|v| v.as_str()).collect::<Vec<_>>().join(",")))
            })
            .collect();
        Ok(Self { given })
    }

    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        // Settings given again replace their earlier values; the others stay.
        for (setting, value) in Self::from_arg_matches(matches)?.given {
            self.given.retain(|(s, _)| s.name != setting.name);
            self.given.push((setting, value));
        }
        Ok(())
    }
}

impl clap::Args for ServeArgs {
    fn augment_args(command: clap::Command) -> clap::Command {
        SETTINGS.iter().fold(command, |command, s| match s.flag {
            Some(flag) => {
                let arg = clap::Arg::new(flag).long(flag).value_name(s.value_name).help(s.flag_help());
                command.arg(if s.is_list() { arg.action(clap::ArgAction::Append) } else { arg })
            }
            None => command,
        })
    }

    fn augment_args_for_update(command: clap::Command) -> clap::Command {
        Self::augment_args(command)
    }
}

impl ServeArgs {
    fn config(&self) -> Result<Config> {
        let mut raw = RawConfig::from_env();
        for (setting, value) in &self.given {
            raw.set_from_flag(setting, value.clone());
        }
        Ok(Config::try_from(raw)?)
    }
}

pub(crate) fn serve(args: &ServeArgs) -> Result<()> {
    let config = args.config()?;
    meshfit::telemetry::init(&config);
    let runtime =
        tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting tokio")?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(config.addr)
            .await
            .with_context(|| format!("cannot listen on {}", config.addr))?;
        let addr = listener.local_addr()?;
        let url = page_url(addr);
        let reach = match addr.ip() {
            ip if ip.is_loopback() => "this machine only (MESHFIT_ADDR=0.0.0.0:8080 serves others)",
            ip if ip.is_unspecified() => "every interface",
            _ => "this address",
        };
        tracing::info!(
            open = %url,
            %addr,
            reach,
            workers = config.pool.workers,
            queue = config.pool.queue,
            api_keys = if config.callers.api_keys.is_empty() { "off: the API is open" } else { "on" },
            cache_dir = config.cache.dir.as_ref().map_or("none: memory only".into(), |d| d.display().to_string()),
            memory_budget = %Bytes(config.pool.memory_bytes),
            cache = %Bytes(config.cache.memory_bytes),
            "meshfit listening"
        );
        meshfit::serve(listener, config, shutdown_signal()).await.context("serving")
    })
}

/// The address a person opens for a server listening on `addr`: a wildcard address listens
/// on every interface, loopback included.
fn page_url(addr: SocketAddr) -> String {
    let ip = if addr.ip().is_unspecified() { "localhost".to_owned() } else { addr.ip().to_string() };
    let host = if addr.is_ipv6() && ip != "localhost" { format!("[{ip}]") } else { ip };
    format!("http://{host}:{}/", addr.port())
}

/// Ctrl-C or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = term => {}
    }
}
