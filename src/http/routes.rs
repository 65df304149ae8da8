//! The routes, each to its handler, and the layers around them, listed outside-in.

use super::problem::ApiError;
use super::state::AppState;
use super::{access, client, evaluate, head, health, jobs, materials, page, tiles};
use crate::config::Config;
use crate::metrics::RequestLabels;
use axum::Router;
use axum::extract::{Request, State};
use axum::http::{HeaderName, HeaderValue, Method, header};
use axum::middleware::{self, Next};
use axum::response::IntoResponse;
use axum::response::Response;
use axum::routing::{get, post};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tower::ServiceBuilder;
use tower_http::LatencyUnit;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::{DefaultOnResponse, TraceLayer};
use tracing::Level;

/// The API's routes, as listed in openapi.yaml.
pub const ROUTES: &[(&str, &str)] = &[
    ("post", "/v1/meshes"),
    ("post", "/v1/solutions"),
    ("post", "/v1/jobs"),
    ("get", "/v1/jobs"),
    ("get", "/v1/jobs/{id}"),
    ("delete", "/v1/jobs/{id}"),
    ("get", "/v1/jobs/{id}/events"),
    ("get", "/v1/jobs/{id}/mesh"),
    ("post", "/v1/jobs/{id}/evaluate"),
    ("get", "/v1/jobs/{id}/ask"),
    ("post", "/v1/jobs/{id}/tell"),
    ("get", "/v1/materials"),
    ("post", "/v1/datasets"),
    ("get", "/v1/datasets"),
    ("get", "/v1/datasets/{id}"),
    ("delete", "/v1/datasets/{id}"),
    ("get", "/v1/tiles/{id}/layer.json"),
    ("get", "/v1/tiles/{id}/{z}/{x}/{y}.terrain"),
    ("get", "/healthz"),
    ("get", "/readyz"),
    ("get", "/metrics"),
    ("get", "/openapi.yaml"),
    ("get", "/"),
    ("get", "/assets/{name}"),
];

/// The router with all layers; tests drive it through a real listener.
pub fn router(state: AppState, config: &Config) -> Router {
    let access = Arc::new(access::Access {
        keys: config.callers.api_keys.clone(),
        origins: config.callers.cors_origins.clone().into(),
        trusted_proxies: config.callers.trusted_proxies.clone().into(),
    });
    // Layers run outside-in: an unsafe request id is dropped first, then every request gets
    // one, so the trace span, every log line and every response carry it.
    let layers = ServiceBuilder::new()
        .layer(middleware::from_fn(head::sanitize_request_id))
        .layer(SetRequestIdLayer::x_request_id(MakeRequestUuid))
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(|req: &Request| {
                    let id = req.headers().get("x-request-id").and_then(|v| v.to_str().ok()).unwrap_or("");
                    // Values are quoted (Debug), so no client text can forge a log field.
                    tracing::info_span!("request", method = %req.method(), path = ?req.uri().path(), request_id = ?id, job_id = tracing::field::Empty)
                })
                // One line per response with its status and latency, inside the span above.
                .on_response(DefaultOnResponse::new().level(Level::INFO).latency_unit(LatencyUnit::Micros))
                // A 5xx is logged where it is made: internal errors at error level, refusals
                // (queue full, shutting down) only in the response line above.
                .on_failure(()),
        )
        .layer(PropagateRequestIdLayer::x_request_id())
        .option_layer(cors(&config.callers.cors_origins))
        // A panicking handler answers a generic 500 problem (logged in the request's span)
        // instead of dropping the connection.
        .layer(CatchPanicLayer::custom(|panic: Box<dyn std::any::Any + Send>| {
            let detail = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a handler panicked".into());
            ApiError::Internal(detail).into_response()
        }))
        .layer(middleware::from_fn_with_state(state.clone(), record_metrics))
        .layer(middleware::from_fn(head::check_sizes))
        .layer(middleware::from_fn_with_state(access, access::check));
    Router::new()
        .route("/v1/meshes", post(jobs::meshes_create))
        .route("/v1/solutions", post(jobs::solutions_create))
        .route("/v1/jobs", post(jobs::jobs_create).get(jobs::jobs_list))
        .route("/v1/jobs/{id}", get(jobs::jobs_show).delete(jobs::jobs_cancel))
        .route("/v1/jobs/{id}/events", get(jobs::jobs_events))
        .route("/v1/jobs/{id}/mesh", get(jobs::jobs_mesh))
        .route("/v1/jobs/{id}/evaluate", post(evaluate::jobs_evaluate))
        .route("/v1/jobs/{id}/ask", get(client::jobs_ask))
        .route("/v1/jobs/{id}/tell", post(client::jobs_tell))
        .route("/v1/materials", get(materials::materials_list))
        .route("/v1/datasets", post(tiles::datasets_create).get(tiles::datasets_list))
        .route("/v1/datasets/{id}", get(tiles::datasets_show).delete(tiles::datasets_delete))
        .route("/v1/tiles/{id}/layer.json", get(tiles::tiles_layer))
        .route("/v1/tiles/{id}/{z}/{x}/{y}", get(tiles::tiles_tile))
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/metrics", get(health::metrics))
        .route("/openapi.yaml", get(health::openapi))
        .route("/", get(page::index))
        .route("/assets/{name}", get(page::asset))
        .fallback(|| async { ApiError::NotFound("no such route; see GET /openapi.yaml".into()) })
        .method_not_allowed_fallback(|| async { ApiError::MethodNotAllowed })
        .layer(layers)
        .with_state(state)
}

/// CORS headers for the listed origins; none when the list is empty (CORS off).
fn cors(origins: &[String]) -> Option<CorsLayer> {
    if origins.is_empty() {
        return None;
    }
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        AllowOrigin::list(origins.iter().filter_map(|o| HeaderValue::from_str(o).ok()))
    };
    let exposed = ["location", "etag", "retry-after", "x-request-id", "x-cache", "server-timing"];
    Some(
        CorsLayer::new()
            .allow_origin(allow)
            .allow_methods([Method::GET, Method::POST, Method::DELETE])
            .allow_headers([
                header::CONTENT_TYPE,
                header::AUTHORIZATION,
                header::ACCEPT,
                HeaderName::from_static("x-request-id"),
            ])
            .expose_headers(exposed.map(HeaderName::from_static))
            .max_age(Duration::from_secs(3600)),
    )
}

/// Counts requests by method and status and records latency to the response head.
async fn record_metrics(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let start = Instant::now();
    // A fixed set: any token is a valid method, and each label set lives forever.
    let method = match *req.method() {
        Method::GET => "GET",
        Method::POST => "POST",
        Method::DELETE => "DELETE",
        Method::HEAD => "HEAD",
        _ => "OTHER",
    };
    let response = next.run(req).await;
    let metrics = state.jobs.metrics();
    metrics.http_latency.observe(start.elapsed().as_secs_f64());
    metrics.http_requests.get_or_create(&RequestLabels { method, status: response.status().as_u16() }).inc();
    response
}
