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
//! - a cap: at `max_connections`, a new connection closes the oldest open one that has no
//!   request in flight (one that has sent nothing yet, or sits idle between requests), as
//!   mature servers drain idle connections when out of slots, so an idle flood cannot keep
//!   `/healthz` or real requests out until the header timeout. When every connection is
//!   busy, a few more are served one request each, `/healthz` as usual and everything else a
//!   503 problem, and beyond those a connection is closed as soon as it is accepted. The cap
//!   sits below the file limit, so `accept` keeps working and the health check keeps
//!   answering.
//!
//! The body timeouts are kept where the body is read, in `super::extract::Body`.

use super::problem::ApiError;
use crate::config::Connections;
use crate::metrics::Metrics;
use axum::Router;
use axum::body::Body;
use axum::extract::{ConnectInfo, Request};
use axum::response::IntoResponse;
use hyper::body::{Frame, Incoming, SizeHint};
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::collections::BTreeMap;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Notify, mpsc, watch};
use tokio_io_timeout::TimeoutStream;
use tower::ServiceExt;

/// Connections served past the cap, one request each, so that `/healthz` answers and others
/// learn why they are refused. (The default cap, [`crate::config::default_max_connections`],
/// leaves file descriptors for them.)
const OVERFLOW: usize = 64;

/// How long an overflow connection may take to send its one request's headers.
const OVERFLOW_HEADER_TIMEOUT: Duration = Duration::from_secs(2);

/// How long to wait before accepting again when the process is out of file descriptors.
const ACCEPT_BACKOFF: Duration = Duration::from_millis(100);

/// Serves `app` on `listener` until `shutdown` resolves, then stops accepting and returns
/// once every open connection has finished its request in flight.
///
/// # Errors
/// Never today: accept errors are logged and retried, as a listener's errors are per
/// connection or transient (out of file descriptors).
pub async fn serve(
    listener: TcpListener,
    app: Router,
    settings: Connections,
    metrics: Arc<Metrics>,
    shutdown: impl Future<Output = ()>,
) -> std::io::Result<()> {
    // Told to every connection at shutdown; `finished` yields once every connection has
    // dropped its sender (mini-redis's shutdown pattern).
    let (stopping, _) = watch::channel(false);
    let (alive, mut finished) = mpsc::channel::<()>(1);
    let (open, overflow) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicUsize::new(0)));
    let below_cap = Arc::new(Registry::default());
    let mut next_id = 0u64;
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
        let (counter, full) = if open.load(Ordering::SeqCst) < settings.max || below_cap.close_oldest_idle() {
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
        next_id += 1;
        let registered = (!full).then(|| Registered::new(&below_cap, next_id));
        let activity = registered.as_ref().map(|r| r.activity.clone());
        let io = TokioIo::new(Box::pin(with_write_timeout(stream, settings.write_timeout)));
        let mut builder = http1::Builder::new();
        let header_timeout = if full { OVERFLOW_HEADER_TIMEOUT } else { settings.header_timeout };
        builder.timer(TokioTimer::new()).header_read_timeout(header_timeout).keep_alive(!full);
        let (app, busy) = (app.clone(), activity.clone());
        let service = TowerToHyperService::new(tower::service_fn(move |req: Request<Incoming>| {
            let mut req = req.map(Body::new);
            req.extensions_mut().insert(ConnectInfo(peer));
            let app = app.clone();
            // In flight from the request's headers to the end of its response's body.
            let in_flight = InFlight::start(busy.clone());
            async move {
                let response = if full && req.uri().path() != "/healthz" {
                    ApiError::TooManyConnections.into_response()
                } else {
                    app.oneshot(req).await?
                };
                Ok::<_, std::convert::Infallible>(
                    response.map(|body| Tracked { body, _in_flight: in_flight }),
                )
            }
        }));
        let connection = builder.serve_connection(io, service);
        let (mut stopping, alive) = (stopping.subscribe(), alive.clone());
        tokio::spawn(async move {
            let mut connection = std::pin::pin!(connection);
            let mut closing = false;
            loop {
                let told_to_close = async {
                    match &activity {
                        Some(a) => a.close.notified().await,
                        None => std::future::pending().await,
                    }
                };
                tokio::select! {
                    ended = connection.as_mut() => {
                        if let Err(e) = ended {
                            tracing::debug!(%peer, error = %e, "connection ended with an error");
                        }
                        break;
                    }
                    // Given way to a new connection, or the server stops: hyper closes an idle
                    // connection at once and a busy one once its response is written.
                    () = told_to_close, if !closing => {
                        tracing::debug!(%peer, "closing an idle connection to admit a new one");
                        closing = true;
                        connection.as_mut().graceful_shutdown();
                    }
                    _ = stopping.wait_for(|&s| s), if !closing => {
                        closing = true;
                        connection.as_mut().graceful_shutdown();
                    }
                }
            }
            drop((registered, slot, alive));
        });
    }
    drop(listener);
    stopping.send_replace(true);
    drop(alive);
    let _ = finished.recv().await;
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

/// The connections below the cap, oldest first, so that at the cap the oldest idle one can be
/// closed.
#[derive(Default)]
struct Registry {
    connections: Mutex<BTreeMap<u64, Arc<Activity>>>,
}

/// What the accept loop knows of a connection below the cap.
#[derive(Default)]
struct Activity {
    /// Requests whose response body hyper has not yet taken to its end.
    in_flight: AtomicUsize,
    /// Set once it has been told to close: it is not chosen again.
    closing: AtomicBool,
    /// Tells its task to close it.
    close: Notify,
}

/// A connection's place in the registry, given up when dropped (however its task ends).
struct Registered {
    registry: Arc<Registry>,
    id: u64,
    activity: Arc<Activity>,
}

impl Registered {
    fn new(registry: &Arc<Registry>, id: u64) -> Self {
        let activity = Arc::new(Activity::default());
        registry.lock().insert(id, activity.clone());
        Self { registry: registry.clone(), id, activity }
    }
}

impl Drop for Registered {
    fn drop(&mut self) {
        self.registry.lock().remove(&self.id);
    }
}

impl Registry {
    /// Tells the oldest connection with no request in flight to close; whether there was one.
    fn close_oldest_idle(&self) -> bool {
        let connections = self.lock();
        let idle = connections
            .values()
            .find(|a| a.in_flight.load(Ordering::SeqCst) == 0 && !a.closing.swap(true, Ordering::SeqCst));
        // notify_one keeps the permit if the task is not waiting yet.
        idle.map(|a| a.close.notify_one()).is_some()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<u64, Arc<Activity>>> {
        // The map stays whole whatever panicked while it was held: take it anyway.
        self.connections.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// A request in flight on a connection below the cap, until dropped.
struct InFlight(Option<Arc<Activity>>);

impl InFlight {
    fn start(activity: Option<Arc<Activity>>) -> Self {
        if let Some(a) = &activity {
            a.in_flight.fetch_add(1, Ordering::SeqCst);
        }
        Self(activity)
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        if let Some(a) = &self.0 {
            a.in_flight.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

/// A response body that keeps its request in flight until hyper has written it and drops it.
struct Tracked {
    body: Body,
    _in_flight: InFlight,
}

impl hyper::body::Body for Tracked {
    type Data = <Body as hyper::body::Body>::Data;
    type Error = <Body as hyper::body::Body>::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Self::Error>>> {
        Pin::new(&mut self.body).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.body.size_hint()
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
