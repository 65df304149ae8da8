//! meshfit: piecewise linear approximation of F(x, y) on a rectangle by a triangle mesh,
//! refined by dividing the worst segment.
//!
//! # Layout
//! Data flows one way: `source` says what F is, `refine` builds the mesh by asking `source`
//! for values and `geom` for topology, `solve` drives the same refinement from a computed
//! solution, `result` holds a finished run as data (geometry, named fields, stats), and
//! `output` encodes it in the format a client asks for. `jobs` is the one bridge from the
//! async service to that engine.
//!
//! - [`geom`]: points, the rectangle, the half-edge mesh, edge splits and flips, constrained
//!   edges (regions' sides, the first mesh from `spade`), exact predicates (`robust`) and
//!   invariant checks.
//! - [`source`]: the [`Surface`](source::Surface) trait and its two sources, a `meval`
//!   expression compiled once and a sampled grid with bilinear interpolation, and
//!   [`decode_grid`](source::decode_grid), which reads a grid from .npy, PNG, TIFF/GeoTIFF,
//!   raw or JSON bytes.
//! - [`refine`]: the refinement loop, its parameters (checked by their builder), the
//!   worst-edge queue, the measures of a finished mesh (V_n, E_n), and a run's trace with the
//!   replay of any prefix of it.
//! - [`result`]: a finished run as data: arrays, named fields per vertex or triangle (with
//!   units), stats, trace; its checksummed binary form, and point location for F_n anywhere.
//! - [`solve`]: P1 finite elements on a mesh's vertices and triangles: −∇·(k ∇u) = f with
//!   Dirichlet, Neumann, periodic and open sides, planar or axisymmetric, regions that are
//!   rectangles or polygons, B–H curves solved by Newton, magnets, coils on circuits and their
//!   inductance, region forces, the material library, a sparse Cholesky solve, error norms
//!   against an exact solution, the adaptive loop, and each physics' derived fields.
//! - [`tiles`]: terrain tiles for web maps: the geographic z/x/y scheme with each level's
//!   error, a tile's crack-free mesh of a DEM (its sides fixed from their own values, then
//!   `refine`'s node insertion), its WGS84 header geometry, and quantized-mesh-1.0.
//! - [`datasets`]: the DEMs the service makes terrain tiles of (uploaded, or files its
//!   settings name), held under the memory budget, and the tiles made, gzipped, in a cache.
//! - [`output`]: the formats (json, obj, ply, stl, vtu, msh, glb, svg, png), each streamed
//!   from a result and looping over its fields; shared by the command line and the API.
//! - [`spec`]: a request checked against the server's limits and mapped to the engine's
//!   types, whose constructors hold the engine's rules, as a canonical, hashed job spec; and a
//!   solution's result mapped back to the request's units.
//! - [`jobs`]: the job table, admission (the bounded worker pool, each client's share of it,
//!   the memory budget), the worker, the cache of results, and the replica protocol behind
//!   one trait ([`jobs::peers::Peers`]).
//! - [`cluster`]: Redis, for replicas that share results and jobs: implements
//!   [`jobs::peers::Peers`] in keys, scripts and channels.
//! - [`http`]: connections (their cap and timeouts), access (keys, origins), routes,
//!   handlers, problem documents, server-sent events, and the page at `/`.
//! - [`cpu`]: where CPU-bound work runs: the blocking pool, below the async workers' priority.
//! - [`config`]: every setting, declared once in [`config::SETTINGS`] (variable, flag,
//!   default, help, parser), arriving grouped by the part of the service that takes it.
//! - [`api`]: the wire types; [`metrics`] and [`telemetry`] support the service.
//!
//! Every arrow between these modules, and no other (`tests/layout.rs` checks both, and that no
//! two files import each other in a circle):
//!
//! ```text
//! geom      ──▶ (nothing)
//! source    ──▶ geom
//! refine    ──▶ geom, source
//! result    ──▶ geom, refine
//! solve     ──▶ geom, refine, result
//! output    ──▶ geom, result
//! tiles     ──▶ geom, refine, source
//! api       ──▶ refine, result, solve, source
//! spec      ──▶ api, geom, refine, result, solve, source
//! jobs      ──▶ api, cpu, geom, metrics, refine, result, solve, source, spec
//! datasets  ──▶ cpu, jobs, source, spec, tiles
//! cluster   ──▶ config, jobs
//! config    ──▶ datasets, jobs, refine, spec
//! telemetry ──▶ config
//! http      ──▶ api, config, cpu, datasets, geom, jobs, metrics, output, refine, result, source, spec, tiles
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod api;
pub mod cluster;
pub mod config;
pub mod cpu;
pub mod datasets;
pub mod geom;
pub mod http;
pub mod jobs;
pub mod metrics;
pub mod output;
pub mod refine;
pub mod result;
pub mod solve;
pub mod source;
pub mod spec;
pub mod telemetry;
pub mod tiles;

use config::Config;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;

/// How long connections may drain after the grace period before the server stops anyway.
const DRAIN_MARGIN: Duration = Duration::from_secs(5);

/// Serves the API on `listener` until `shutdown` resolves, then stops taking jobs, lets
/// running ones finish for `config.shutdown_grace`, cancels the rest and returns.
///
/// The caller binds the listener (tests bind port 0) and chooses the shutdown signal, as in
/// mini-redis's `server::run`.
///
/// # Errors
/// When the cache directory cannot be created or the listener fails.
pub async fn serve(
    listener: TcpListener,
    config: Config,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let mut metrics = metrics::Metrics::default();
    if config.redis.url.is_some() {
        metrics.register_redis();
    }
    let metrics = Arc::new(metrics);
    // Opening a cache directory lists it and may prune it: blocking work.
    let settings = config.cache.clone();
    let cache = tokio::task::spawn_blocking(move || {
        jobs::Cache::open(&settings).map_err(|e| {
            let path = settings.dir.as_ref().map(|d| d.display().to_string()).unwrap_or_default();
            std::io::Error::new(
                e.kind(),
                format!("MESHFIT_CACHE_DIR={path}: cannot use it as the cache directory: {e}"),
            )
        })
    })
    .await
    .map_err(std::io::Error::other)??;
    let mut jobs = jobs::Jobs::new(&config.pool, cache, metrics.clone());
    let mut peers: Option<Arc<dyn jobs::peers::Peers>> = None;
    if let Some(url) = &config.redis.url {
        let cluster = cluster::Cluster::connect(url, config.redis.clone(), metrics.redis_errors.clone())
            .map_err(|e| std::io::Error::other(format!("MESHFIT_REDIS_URL: {e}")))?;
        tracing::info!(replica = cluster.replica(), "sharing results, jobs and datasets through redis");
        let cluster: Arc<dyn jobs::peers::Peers> = Arc::new(cluster);
        jobs = jobs.shared(cluster.clone(), config.limits);
        peers = Some(cluster);
    }
    // The files the settings name are read once, before the first request.
    let datasets = datasets::Datasets::new(config.datasets.clone(), jobs.budget().clone(), peers);
    let opening = datasets.clone();
    tokio::task::spawn_blocking(move || opening.open_files())
        .await
        .map_err(std::io::Error::other)?
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
    // Indexes are rebuilt in milliseconds; a quarter of the result cache's budget holds plenty.
    let locator_bytes = config.cache.memory_bytes / 4;
    let keyed = !config.callers.api_keys.is_empty();
    let state = http::AppState::new(jobs.clone(), datasets, keyed, config.limits, config.body, locator_bytes);
    let app = http::router(state, &config);
    let on_signal = jobs.clone();
    let grace = config.shutdown_grace;
    let (signalled, mut on_signalled) = tokio::sync::watch::channel(false);
    let server = http::conn::serve(listener, app, config.connections, jobs.metrics().clone(), async move {
        shutdown.await;
        tracing::info!(grace_ms = grace.as_millis() as u64, "shutting down: no new jobs");
        on_signal.close();
        let _ = signalled.send(true);
        // Open requests and streams end when their jobs do; past the grace period, make
        // them end.
        tokio::spawn(async move {
            tokio::time::sleep(grace).await;
            on_signal.cancel_all();
        });
    });
    // A connection can outlive its job (a slow reader of a large mesh): after the grace
    // period and a margin to drain, stop waiting for it.
    let hard_stop = async move {
        let _ = on_signalled.wait_for(|&s| s).await;
        tokio::time::sleep(grace + DRAIN_MARGIN).await;
    };
    tokio::select! {
        served = server => served?,
        () = hard_stop => tracing::warn!("connections still open after the grace period; closing them"),
    }
    // Detached jobs have no connection to wait on: give them the same grace.
    let deadline = tokio::time::Instant::now() + grace;
    while jobs.is_busy() {
        if tokio::time::Instant::now() >= deadline {
            jobs.cancel_all();
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    tracing::info!("stopped");
    Ok(())
}
