//! `meshfit health`: one GET /healthz, for a container's HEALTHCHECK.

use anyhow::{Context, Result, bail};
use clap::Args;
use meshfit::config::{Config, RawConfig};
use std::io::Write;
use std::time::Duration;

#[derive(Args)]
pub(crate) struct HealthArgs {
    /// The server's address, as MESHFIT_ADDR takes it; a wildcard address (0.0.0.0, [::]) is
    /// asked on loopback [default: MESHFIT_ADDR, else 0.0.0.0:8080].
    #[arg(long, value_name = "HOST:PORT")]
    addr: Option<String>,
}

/// How long `meshfit health` waits for the connection and for the answer, each.
const HEALTH_TIMEOUT: Duration = Duration::from_secs(3);

/// One GET /healthz over a plain socket: the binary carries no HTTP client (reqwest is for
/// tests), and the check needs no more than a status line.
pub(crate) fn health(args: &HealthArgs) -> Result<()> {
    use std::io::Read;
    use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, TcpStream};
    // The address the server takes: from the same settings table, unless --addr names one.
    let mut addr = match &args.addr {
        Some(text) => {
            meshfit::config::listen_addr(text).map_err(|why| anyhow::anyhow!("--addr {text:?}: {why}"))?
        }
        None => Config::try_from(RawConfig::from_env())?.addr,
    };
    if addr.ip().is_unspecified() {
        addr.set_ip(match addr.ip() {
            IpAddr::V4(_) => IpAddr::V4(Ipv4Addr::LOCALHOST),
            IpAddr::V6(_) => IpAddr::V6(Ipv6Addr::LOCALHOST),
        });
    }
    let mut stream = TcpStream::connect_timeout(&addr, HEALTH_TIMEOUT)
        .with_context(|| format!("no server answers at {addr}"))?;
    stream.set_read_timeout(Some(HEALTH_TIMEOUT))?;
    stream.set_write_timeout(Some(HEALTH_TIMEOUT))?;
    write!(stream, "GET /healthz HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n")?;
    let mut head = [0u8; 64];
    let n = stream.read(&mut head).with_context(|| format!("the server at {addr} did not answer"))?;
    let status_line = String::from_utf8_lossy(&head[..n]);
    let status_line = status_line.lines().next().unwrap_or("");
    match status_line.split(' ').nth(1) {
        Some("200") => Ok(()),
        _ => bail!("GET http://{addr}/healthz answered {status_line:?}"),
    }
}
