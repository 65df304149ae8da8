//! Checks on a request's head before anything else sees it: the size of its target and
//! headers, and whether its `x-request-id` is safe to log and echo.

use super::problem::ApiError;
use axum::extract::Request;
use axum::http::HeaderName;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

/// Longest request target (path and query) in bytes; past it, 414.
pub const MAX_TARGET_BYTES: usize = 8 << 10;

/// Most bytes of header names and values together; past it, 431. hyper's own limit (its
/// read buffer) stays as a backstop for larger heads, which it refuses without a body.
pub const MAX_HEADER_BYTES: usize = 32 << 10;

/// Longest request id kept from a client.
pub const MAX_REQUEST_ID_LEN: usize = 128;

static X_REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// Whether a client's request id may be kept: short, and only characters that need no
/// quoting in a log line or a header (letters, digits and `-_.:/+=@`).
pub fn is_safe_request_id(id: &[u8]) -> bool {
    (1..=MAX_REQUEST_ID_LEN).contains(&id.len())
        && id.iter().all(|&b| b.is_ascii_alphanumeric() || b"-_.:/+=@".contains(&b))
}

/// Drops an unsafe `x-request-id`, so that the request-id layer inside this one gives the
/// request a fresh one (a client's text is never echoed or logged unless it is plain).
pub async fn sanitize_request_id(mut req: Request, next: Next) -> Response {
    if let Some(id) = req.headers().get(&X_REQUEST_ID)
        && !is_safe_request_id(id.as_bytes())
    {
        req.headers_mut().remove(&X_REQUEST_ID);
    }
    next.run(req).await
}

/// Refuses an oversized request target (414) or headers (431) with a problem document.
pub async fn check_sizes(req: Request, next: Next) -> Response {
    let target = req.uri().path_and_query().map_or(0, |pq| pq.as_str().len());
    if target > MAX_TARGET_BYTES {
        return ApiError::TargetTooLong(MAX_TARGET_BYTES).into_response();
    }
    let headers: usize = req.headers().iter().map(|(k, v)| k.as_str().len() + v.len()).sum();
    if headers > MAX_HEADER_BYTES {
        return ApiError::HeadersTooLarge(MAX_HEADER_BYTES).into_response();
    }
    next.run(req).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_ids_are_kept_only_when_short_and_plain() {
        for kept in
            ["abc-123", "0f8e2c1a-7d3b-4c5e-9a1f-2b3c4d5e6f70", "trace:span/1+x=y@z", &"a".repeat(128)]
        {
            assert!(is_safe_request_id(kept.as_bytes()), "{kept}");
        }
        for dropped in ["", "a b", "x\" level=error", "line\nbreak", "é", &"a".repeat(129)] {
            assert!(!is_safe_request_id(dropped.as_bytes()), "{dropped:?}");
        }
    }
}
