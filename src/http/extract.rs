//! The request body as bytes, with a rejection that is a problem document, and JSON parsing
//! whose errors are problems too (axum's AppJson pattern).

use super::problem::ApiError;
use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::StatusCode;
use serde::de::DeserializeOwned;

/// The raw body, bounded by the router's `DefaultBodyLimit`.
pub struct Body(pub Bytes);

/// The body limit, so a rejection can name it.
#[derive(Clone, Copy)]
pub struct BodyLimit(pub usize);

impl<S: Send + Sync> FromRequest<S> for Body {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, ApiError> {
        let limit = req.extensions().get::<BodyLimit>().map_or(0, |l| l.0);
        match Bytes::from_request(req, state).await {
            Ok(bytes) => Ok(Body(bytes)),
            Err(e) if e.status() == StatusCode::PAYLOAD_TOO_LARGE => Err(ApiError::BodyTooLarge(limit)),
            Err(e) => Err(ApiError::MalformedJson(e.body_text())),
        }
    }
}

/// Parses JSON, telling syntax errors (400) from shape errors (422), each with its place.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(ApiError::MalformedJson("the body is empty; send a JSON object".into()));
    }
    let malformed = |e: serde_json::Error| match e.classify() {
        serde_json::error::Category::Data => ApiError::InvalidRequest(e.to_string()),
        _ => ApiError::MalformedJson(e.to_string()),
    };
    // serde's derived structs also take arrays (as tuples); a request is an object.
    if bytes.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'{') {
        serde_json::from_slice::<serde::de::IgnoredAny>(bytes).map_err(malformed)?;
        return Err(ApiError::InvalidRequest("the body must be a JSON object".into()));
    }
    serde_json::from_slice(bytes).map_err(malformed)
}
