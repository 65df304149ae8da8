//! Liveness, readiness, metrics and the API description.

use super::state::AppState;
use axum::Json;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use serde_json::json;

/// `GET /healthz`: the process answers. Never touches the job machinery, so it stays fast
/// while every worker is busy.
pub async fn healthz() -> impl IntoResponse {
    Json(json!({"status": "ok"}))
}

/// `GET /readyz`: 200 while the server takes jobs, 503 when its queue is full or it is
/// shutting down. When replicas share through Redis, `redis` says whether it answers; a
/// replica without it still serves (alone), so it stays ready.
pub async fn readyz(State(state): State<AppState>) -> impl IntoResponse {
    let (code, status) = match state.jobs.is_ready() {
        true => (StatusCode::OK, "ready"),
        false => (StatusCode::SERVICE_UNAVAILABLE, "busy"),
    };
    let body = match state.jobs.redis() {
        None => json!({"status": status}),
        Some(up) => json!({"status": status, "redis": if up { "up" } else { "down" }}),
    };
    (code, Json(body))
}

/// `GET /metrics`: Prometheus text format.
pub async fn metrics(State(state): State<AppState>) -> impl IntoResponse {
    let metrics = state.jobs.metrics();
    metrics.cache_bytes.set(i64::try_from(state.jobs.cache_bytes()).unwrap_or(i64::MAX));
    metrics.cache_disk_bytes.set(i64::try_from(state.jobs.cache_disk_bytes()).unwrap_or(i64::MAX));
    let budget = state.jobs.budget();
    metrics.memory_budget_bytes.set(i64::try_from(budget.limit()).unwrap_or(i64::MAX));
    metrics.memory_charged_bytes.set(i64::try_from(budget.charged()).unwrap_or(i64::MAX));
    if let Some(up) = state.jobs.redis() {
        metrics.redis_up.set(i64::from(up));
    }
    ([(header::CONTENT_TYPE, "application/openmetrics-text; version=1.0.0; charset=utf-8")], metrics.encode())
}

/// The OpenAPI description, compiled into the binary so it always matches it.
pub const OPENAPI: &str = include_str!("../../openapi.yaml");

/// `GET /openapi.yaml`.
pub async fn openapi() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "application/yaml")], OPENAPI)
}
