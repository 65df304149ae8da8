//! `GET /v1/materials`: the built-in materials a device's regions may name.

use crate::spec::materials;
use axum::Json;
use axum::http::header;
use axum::response::IntoResponse;
use serde_json::json;

/// `GET /v1/materials`: every built-in material with its law and the source of its figures.
/// The list is compiled in, so clients may keep it for a day.
pub async fn materials_list() -> impl IntoResponse {
    ([(header::CACHE_CONTROL, "public, max-age=86400")], Json(json!({"materials": materials::library()})))
}
