//! The request body as bytes, with a rejection that is a problem document, and JSON parsing
//! whose errors are problems too (axum's AppJson pattern).

use super::problem::ApiError;
use super::state::AppState;
use crate::config::BodyLimits;
use crate::jobs::{Charge, OverBudget};
use crate::source::signed_kind;
use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{HeaderMap, header};
use bytes::BytesMut;
use futures_util::StreamExt;
use serde::Deserialize;
use std::time::Duration;
use tokio::time::{Instant, timeout};

/// The raw body, read under the body limit and charged to the memory budget while it is
/// held: a declared length is charged before the first byte is read, a chunked body as it
/// grows.
pub struct Body {
    /// The bytes.
    pub bytes: Bytes,
    /// Their share of the memory budget, returned when the body is dropped.
    _charge: Charge,
}

/// The slowest a body may arrive on average, in bytes per second, beyond the body timeout:
/// a client trickling a few bytes a second never pauses long enough for the timeout, and
/// would hold its connection and its charge for hours. 64 KiB/s takes a 256 MiB body in
/// 68 minutes.
pub const MIN_BODY_RATE: u64 = 64 << 10;

impl FromRequest<AppState> for Body {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, ApiError> {
        let BodyLimits { max_bytes: limit, timeout: patience } = state.body;
        let start = Instant::now();
        let declared =
            req.headers().get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()?.parse::<u64>().ok());
        if declared.is_some_and(|n| n > limit as u64) {
            return Err(ApiError::BodyTooLarge(limit));
        }
        let over = |o: OverBudget| {
            state.jobs.metrics().memory_refusals.inc();
            ApiError::OverBudget(o.needed, o.available, state.jobs.retry_after())
        };
        let declared = declared.unwrap_or(0);
        let mut charge = state.jobs.budget().charge(declared).map_err(over)?;
        let mut body = BytesMut::with_capacity(declared as usize);
        let mut stream = req.into_body().into_data_stream();
        // Each part must come within the timeout, and the whole at the minimum rate beyond it.
        while let Some(chunk) = timeout(patience, stream.next()).await.map_err(|_| ApiError::BodyTimeout)? {
            let chunk =
                chunk.map_err(|e| ApiError::MalformedJson(format!("the body could not be read: {e}")))?;
            let len = body.len() + chunk.len();
            if len > limit {
                return Err(ApiError::BodyTooLarge(limit));
            }
            let allowed = patience.saturating_add(Duration::from_secs_f64(len as f64 / MIN_BODY_RATE as f64));
            if start.elapsed() > allowed {
                return Err(ApiError::BodyTimeout);
            }
            charge.grow_to(len as u64).map_err(over)?;
            body.extend_from_slice(&chunk);
        }
        Ok(Body { bytes: body.freeze(), _charge: charge })
    }
}

/// Parses JSON, telling syntax errors (400, at a line and column) from shape errors (422, at
/// a field).
pub fn parse_json<'a, T: Deserialize<'a>>(bytes: &'a [u8]) -> Result<T, ApiError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(ApiError::MalformedJson("the body is empty; send a JSON object".into()));
    }
    crate::api::from_json(bytes).map_err(|e| match signed_kind(bytes) {
        Some(kind) => ApiError::MalformedJson(format!(
            "the body is a {kind} file, not JSON; a grid file goes as multipart/form-data: {UPLOAD}"
        )),
        None => ApiError::Json(e),
    })
}

/// Whether a JSON body has the top-level field `key`, not null (false when it does not parse:
/// the route's parser then says what is wrong). `POST /v1/jobs` reads what a body is by it.
///
/// A byte search goes first, so a large grid body without the word is not parsed a second
/// time just to find out. A key spelled with escapes (`"\u0070hysics"`) is not found.
pub fn names(json: &[u8], key: &str) -> bool {
    use serde::de::IgnoredAny;
    memchr::memmem::find(json, format!("\"{key}\"").as_bytes()).is_some()
        && serde_json::from_slice::<std::collections::HashMap<String, Option<IgnoredAny>>>(json)
            .is_ok_and(|fields| fields.get(key).is_some_and(Option::is_some))
}

/// How a grid file is sent, for messages.
const UPLOAD: &str = "curl -F grid=@FILE [-F request='{...}']";

/// The media types a route takes besides JSON.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Takes {
    /// `application/json` only.
    Json,
    /// Also `multipart/form-data`: a grid file with its request.
    Upload,
    /// Also `application/octet-stream`: packed little-endian f64s.
    Binary,
}

impl Takes {
    /// The media types, for the 415 answer.
    pub fn types(self) -> &'static [&'static str] {
        match self {
            Takes::Json => &["application/json"],
            Takes::Upload => &["application/json", "multipart/form-data"],
            Takes::Binary => &["application/json", "application/octet-stream"],
        }
    }
}

/// What a body is, by its content type.
#[derive(Debug, Clone, PartialEq)]
pub enum Media {
    /// JSON.
    Json,
    /// `multipart/form-data` with this boundary.
    Multipart(String),
    /// `application/octet-stream`.
    Binary,
}

/// What `body` is, of the types the route takes.
///
/// JSON is `application/json`, any `application/*+json`, or no content type at all;
/// `application/x-www-form-urlencoded` (what curl's `-d` names whatever it sends) is read as
/// JSON when the body is an object.
///
/// # Errors
/// 415 `unsupported-media-type` for any other type (with a hint when the body is a grid file
/// sent raw), 400 for a multipart type without a boundary.
pub fn media(headers: &HeaderMap, body: &[u8], takes: Takes) -> Result<Media, ApiError> {
    let Some(value) = headers.get(header::CONTENT_TYPE) else { return Ok(Media::Json) };
    let text = value.to_str().unwrap_or_default();
    let essence = text.split(';').next().unwrap_or_default().trim().to_ascii_lowercase();
    let object = body.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{');
    let json = essence == "application/json"
        || (essence.starts_with("application/") && essence.ends_with("+json"))
        || (essence == "application/x-www-form-urlencoded" && object);
    match (essence.as_str(), takes) {
        _ if json => return Ok(Media::Json),
        ("multipart/form-data", Takes::Upload) => {
            let boundary =
                multer::parse_boundary(text).map_err(|e| ApiError::MalformedMultipart(e.to_string()))?;
            return Ok(Media::Multipart(boundary));
        }
        ("application/octet-stream", Takes::Binary) => return Ok(Media::Binary),
        _ => {}
    }
    let raw_grid = signed_kind(body).is_some()
        || essence == "application/octet-stream"
        || essence.starts_with("image/")
        || essence == "application/x-npy"
        || essence == "multipart/form-data";
    let hint = match (raw_grid, takes) {
        (true, Takes::Upload) => format!("; a grid file goes as multipart/form-data: {UPLOAD}"),
        (true, Takes::Json) => "; grid files are for POST /v1/meshes and POST /v1/jobs".into(),
        _ => String::new(),
    };
    let types: Vec<String> = takes.types().iter().map(|t| format!("`{t}`")).collect();
    let detail = format!("this route takes {}, not `{essence}`{hint}", types.join(" or "));
    Err(ApiError::UnsupportedMediaType { detail, accepted: takes.types() })
}

/// A job request as sent: a JSON body, or `multipart/form-data` with a `request` part (the
/// JSON, optional) and a `grid` part (a grid file).
pub enum JobBody {
    /// `application/json` (or no content type).
    Json(Bytes),
    /// A grid file with the request that goes with it.
    Upload {
        /// The `request` part, `{}` when absent.
        request: Bytes,
        /// The `grid` part.
        grid: Bytes,
    },
}

impl JobBody {
    /// Splits `body` by its content type (see [`media`]). The whole body is already in
    /// memory, bounded by the body limit; multer (the parser behind axum's own multipart
    /// extractor) finds the parts.
    ///
    /// # Errors
    /// 415 for a content type the route does not take; 400 `malformed-multipart` for a
    /// multipart body that does not parse; 422 for a missing `grid` part, a part sent twice or
    /// a part of another name.
    pub async fn from_parts(headers: &HeaderMap, body: Bytes, takes: Takes) -> Result<Self, ApiError> {
        let Media::Multipart(boundary) = media(headers, &body, takes)? else {
            return Ok(JobBody::Json(body));
        };
        let malformed = |e: multer::Error| ApiError::MalformedMultipart(e.to_string());
        let stream = futures_util::stream::once(async move { Ok::<_, std::convert::Infallible>(body) });
        let mut multipart = multer::Multipart::new(stream, boundary);
        let (mut request, mut grid) = (None, None);
        while let Some(field) = multipart.next_field().await.map_err(malformed)? {
            let name = field.name().unwrap_or("").to_owned();
            let slot = match name.as_str() {
                "request" => &mut request,
                "grid" => &mut grid,
                _ => {
                    return Err(ApiError::InvalidRequest(format!(
                        "multipart part `{name}`: the parts are `request` (JSON) and `grid` (a file)"
                    )));
                }
            };
            if slot.is_some() {
                return Err(ApiError::InvalidRequest(format!("multipart part `{name}` is sent twice")));
            }
            *slot = Some(field.bytes().await.map_err(malformed)?);
        }
        let grid = grid.ok_or_else(|| {
            ApiError::InvalidRequest("a multipart request needs a `grid` part holding the grid file".into())
        })?;
        // An absent or blank `request` part is the empty request.
        let request = request.filter(|r| !r.iter().all(u8::is_ascii_whitespace));
        Ok(JobBody::Upload { request: request.unwrap_or_else(|| Bytes::from_static(b"{}")), grid })
    }
}

/// A request's query string as `T`; a malformed one is a 422 saying what is wrong.
pub(super) fn query<T: serde::de::DeserializeOwned>(uri: &axum::http::Uri) -> Result<T, ApiError> {
    let axum::extract::Query(query) = axum::extract::Query::<T>::try_from_uri(uri)
        .map_err(|e| ApiError::InvalidRequest(format!("query string: {}", e.body_text())))?;
    Ok(query)
}
