//! The page for people at `/`: a form, the mesh as it grows, its convergence and downloads.
//!
//! Plain HTML, CSS and JavaScript compiled into the binary, so `cargo run` serves it offline
//! with no build step. It speaks only the public API (`POST /v1/jobs`, the job's events with
//! `?vertices=true`, `GET /v1/jobs/{id}/mesh?format=`), like any other client.

use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::problem::ApiError;

/// The page's files: name, media type, content.
const ASSETS: &[(&str, &str, &str)] = &[
    ("app.js", "text/javascript; charset=utf-8", include_str!("page/app.js")),
    ("app.css", "text/css; charset=utf-8", include_str!("page/app.css")),
];

/// Scripts and styles only from the server itself; pictures may be blobs the page drew.
const POLICY: &str = "default-src 'self'; img-src 'self' data: blob:; object-src 'none'; base-uri 'none'; \
                      frame-ancestors 'none'; form-action 'self'";

fn page(media: &'static str, body: &'static str) -> Response {
    let mut response = body.into_response();
    let h = response.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(media));
    // Revalidated on every load: a new server version is seen at once.
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    h.insert(header::CONTENT_SECURITY_POLICY, HeaderValue::from_static(POLICY));
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    response
}

/// `GET /`: the page.
pub async fn index() -> Response {
    page("text/html; charset=utf-8", include_str!("page/index.html"))
}

/// `GET /assets/{name}`: its script and style sheet.
pub async fn asset(Path(name): Path<String>) -> Result<Response, ApiError> {
    let (_, media, body) = ASSETS
        .iter()
        .find(|(n, _, _)| *n == name)
        .ok_or_else(|| ApiError::NotFound(format!("no asset {name:?}")))?;
    Ok(page(media, body))
}
