//! Connections: the accept loop, the cap on open connections, and the timeouts that free
//! what a silent client holds.
//!
//! axum's `serve` has neither a cap nor timeouts: idle sockets, half-sent headers and
//! stalled readers stayed open until the file limit was reached and `accept` failed. Here
//! each connection is served by hyper's HTTP/1.1 server directly (its HTTP/2 detection
//! would wait on a silent socket with no timer), with
//! - hyper's header timer, which runs from the end of one response to the end of the next
//!   request's headers, so it closes idle keep-alive connections and slow headers alike;
//! - a write timeout on the socket (`tokio-io-timeout`): a response the client has not read
//!   for that long ends the connection, and the response's buffers are dropped with it;
//! - a cap: past `max_connections`, a few more connections are served one request each,
//!   `/healthz` as usual and everything else a 503 problem, and beyond those a connection
//!   is closed as soon as it is accepted. The cap sits below the file limit, so `accept`
//!   keeps working and the health check keeps answering.
//!
//! The body timeouts are kept where the body is read, in `super::extract::Body`.

use super::problem::ApiError;
use crate::metrics::Metrics;
use axum::Router;
use axum::body::Body;
use axum::extract::{ConnectInfo, Request};
use axum::response::IntoResponse;
use hyper::body::Incoming;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;
use tokio::net::{TcpListener, TcpStream};
use tokio_io_timeout::TimeoutStream;
use tower::ServiceExt;

/// Connections served past the cap, one request each, so that `/healthz` answers and others
/// learn why they are refused.
const OVERFLOW: usize = 64;

/// How long an overflow connection may take to send its one request's headers.
const OVERFLOW_HEADER_TIMEOUT: Duration = Duration::from_secs(2);

/// How long to wait before accepting again when the process is out of file descriptors.
const ACCEPT_BACKOFF: Duration = Duration::from_millis(100);

/// The limits on connections; see the README's table of settings.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Connections served at once.
    pub max_connections: usize,
    /// From the end of a response (or the connection's start) to the end of the next
    /// request's headers.
    pub header_timeout: Duration,
    /// Longest a response write may wait for the client to read.
    pub write_timeout: Duration,
}

/// Serves `app` on `listener` until `shutdown` resolves, then stops accepting and returns
/// once every open connection has finished its request in flight.
///
/// # Errors
/// Never today: accept errors are logged and retried, as a listener's errors are per
/// connection or transient (out of file descriptors).
pub async fn serve(
    listener: TcpListener,
    app: Router,
    settings: Settings,
    metrics: Arc<Metrics>,
    shutdown: impl Future<Output = ()>,
) -> std::io::Result<()> {
    let graceful = GracefulShutdown::new();
    let (open, overflow) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicUsize::new(0)));
    let mut shutdown = std::pin::pin!(shutdown);
    loop {
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(pair) => pair,
                Err(e) => {
                    on_accept_error(&e).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        let _ = stream.set_nodelay(true);
        let (counter, full) = if open.load(Ordering::SeqCst) < settings.max_connections {
            (&open, false)
        } else if overflow.load(Ordering::SeqCst) < OVERFLOW {
            metrics.connections_refused.inc();
            (&overflow, true)
        } else {
            // Dropping the stream closes it; the client sees the connection end at once.
            metrics.connections_refused.inc();
            continue;
        };
        let slot = Slot::take(counter, &metrics);
        let io = TokioIo::new(Box::pin(with_write_timeout(stream, settings.write_timeout)));
        let mut builder = http1::Builder::new();
        let header_timeout = if full { OVERFLOW_HEADER_TIMEOUT } else { settings.header_timeout };
        builder.timer(TokioTimer::new()).header_read_timeout(header_timeout).keep_alive(!full);
        let app = app.clone();
        let service = TowerToHyperService::new(tower::service_fn(move |req: Request<Incoming>| {
            let mut req = req.map(Body::new);
            req.extensions_mut().insert(ConnectInfo(peer));
            let app = app.clone();
            async move {
                if full && req.uri().path() != "/healthz" {
                    return Ok(ApiError::TooManyConnections.into_response());
                }
                app.oneshot(req).await
            }
        }));
        let connection = graceful.watch(builder.serve_connection(io, service));
        tokio::spawn(async move {
            if let Err(e) = connection.await {
                tracing::debug!(%peer, error = %e, "connection ended with an error");
            }
            drop(slot);
        });
    }
    drop(listener);
    graceful.shutdown().await;
    Ok(())
}

fn with_write_timeout(stream: TcpStream, timeout: Duration) -> TimeoutStream<TcpStream> {
    let mut stream = TimeoutStream::new(stream);
    stream.set_write_timeout(Some(timeout));
    stream
}

/// Logs an accept error and, when the process is out of file descriptors, waits before the
/// next accept instead of spinning on the full backlog.
async fn on_accept_error(e: &std::io::Error) {
    // EMFILE and ENFILE: the cap should prevent them; something else holds descriptors.
    let out_of_files = matches!(e.raw_os_error(), Some(23 | 24));
    if out_of_files {
        tracing::warn!(error = %e, "accept failed: out of file descriptors; retrying shortly");
        tokio::time::sleep(ACCEPT_BACKOFF).await;
    } else {
        tracing::debug!(error = %e, "accept failed");
    }
}

/// One open connection, counted while it lives.
struct Slot {
    counter: Arc<AtomicUsize>,
    metrics: Arc<Metrics>,
}

impl Slot {
    fn take(counter: &Arc<AtomicUsize>, metrics: &Arc<Metrics>) -> Self {
        counter.fetch_add(1, Ordering::SeqCst);
        metrics.connections_open.inc();
        Self { counter: counter.clone(), metrics: metrics.clone() }
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.counter.fetch_sub(1, Ordering::SeqCst);
        self.metrics.connections_open.dec();
    }
}

/// The default cap: the process's soft file limit less room for the cache directory's
/// files, the listener and the overflow connections, at most 10,000.
pub fn default_max_connections() -> usize {
    let soft = rustix::process::getrlimit(rustix::process::Resource::Nofile).current;
    let files = soft.map_or(usize::MAX, |n| usize::try_from(n).unwrap_or(usize::MAX));
    files.saturating_sub(OVERFLOW + 192).clamp(16, 10_000)
}
