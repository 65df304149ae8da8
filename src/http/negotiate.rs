//! Which format a response takes, and the response that carries a result in it.
//!
//! `?format=` wins over `Accept`; without either the answer is the JSON document. A format
//! nobody knows is a 406 listing the known ones.

use super::problem::ApiError;
use crate::output::{self, Format, Options};
use crate::result::RunResult;
use axum::body::Body;
use axum::http::{HeaderMap, HeaderValue, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

/// The query string of routes that answer a result.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputQuery {
    format: Option<String>,
    z_scale: Option<f64>,
    size: Option<u32>,
}

/// The largest picture `?size=` may ask for, in pixels a side.
pub const MAX_PICTURE_SIZE: u32 = 8192;

/// What the client asked a result to look like.
#[derive(Debug, Clone, PartialEq)]
pub struct Wanted {
    /// The format.
    pub format: Format,
    /// Options of the encoding (the id is filled in by the response).
    pub options: Options,
}

impl Wanted {
    /// Reads `?format=`, `?z_scale=`, `?size=` and the `Accept` header.
    ///
    /// # Errors
    /// 406 for a format nobody knows; 422 for a malformed query or an option out of range.
    pub fn from_request(uri: &Uri, headers: &HeaderMap) -> Result<Self, ApiError> {
        let query: OutputQuery = super::extract::query(uri)?;
        let format = match &query.format {
            Some(name) => Format::from_name(name).ok_or_else(|| ApiError::NotAcceptable(name.clone()))?,
            None => from_accept(headers)?,
        };
        let mut options = Options::default();
        // An option the format does not take would be ignored without a word.
        let refuse = |option: &str, takes: fn(Format) -> bool| {
            let formats: Vec<&str> = Format::ALL.iter().filter(|f| takes(**f)).map(|f| f.name()).collect();
            ApiError::InvalidRequest(format!(
                "{option} does not apply to format {}; it applies to {}",
                format.name(),
                formats.join(", ")
            ))
        };
        if query.z_scale.is_some() && !format.takes_z_scale() {
            return Err(refuse("z_scale", Format::takes_z_scale));
        }
        if query.size.is_some() && !format.takes_size() {
            return Err(refuse("size", Format::takes_size));
        }
        if let Some(z) = query.z_scale {
            if !z.is_finite() {
                return Err(ApiError::InvalidRequest(format!("z_scale must be a finite number, got {z}")));
            }
            options.z_scale = z + 0.0;
        }
        if let Some(size) = query.size {
            if !(16..=MAX_PICTURE_SIZE).contains(&size) {
                return Err(ApiError::InvalidRequest(format!(
                    "size must be from 16 to {MAX_PICTURE_SIZE} pixels, got {size}"
                )));
            }
            options.size = size;
        }
        Ok(Self { format, options })
    }

    /// The entity tag of `id` in this form: the bare id for the default document, so a format
    /// or option never shares a tag with other bytes.
    fn etag(&self, id: &str) -> HeaderValue {
        let mut tag = format!("\"{id}");
        if self.format != Format::Json {
            tag.push('.');
            tag.push_str(self.format.name());
        }
        let defaults = Options::default();
        if self.options.z_scale != defaults.z_scale {
            tag.push_str(&format!(";z={}", self.options.z_scale));
        }
        if self.options.size != defaults.size {
            tag.push_str(&format!(";size={}", self.options.size));
        }
        tag.push('"');
        HeaderValue::from_str(&tag).expect("hex, a name and numbers make a valid header value")
    }
}

/// The first format the `Accept` header names that we write; `*/*` (or no header) is JSON.
/// `text/event-stream` is left to the routes that stream.
fn from_accept(headers: &HeaderMap) -> Result<Format, ApiError> {
    let mut asked = Vec::new();
    for value in headers.get_all(header::ACCEPT).iter().filter_map(|v| v.to_str().ok()) {
        for range in value.split(',').map(|r| r.split(';').next().unwrap_or("").trim()) {
            if range.is_empty() || range == "text/event-stream" {
                continue;
            }
            if range == "*/*" || range == "application/*" {
                return Ok(Format::Json);
            }
            if let Some(format) = Format::from_media_type(range) {
                return Ok(format);
            }
            asked.push(range.to_owned());
        }
    }
    match asked.is_empty() {
        true => Ok(Format::Json),
        false => Err(ApiError::NotAcceptable(asked.join(", "))),
    }
}

/// Where a response's result came from, for `x-cache`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Provenance {
    /// Computed for this request.
    Miss,
    /// From the cache.
    Hit,
    /// Replayed from a larger cached run of the same family: the bytes of a fresh run.
    Prefix,
    /// A run a time limit stopped: not the request's cached answer, so no entity tag.
    Partial,
}

/// Results up to this many vertices start their JSON encoding on the async worker.
const INLINE_VERTICES: usize = 100_000;

/// `result` of job `id` in the wanted form, or 304 when the client has these bytes.
/// `elapsed` (the engine's time) goes into `Server-Timing`, never into the body.
pub async fn result_response(
    headers: &HeaderMap,
    wanted: &Wanted,
    id: &str,
    result: Arc<RunResult>,
    provenance: Provenance,
    elapsed: Option<Duration>,
) -> Result<Response, ApiError> {
    let etag = (provenance != Provenance::Partial).then(|| wanted.etag(id));
    let mut response = match &etag {
        Some(tag) if not_modified(headers, tag) => StatusCode::NOT_MODIFIED.into_response(),
        _ => {
            let (format, options) =
                (wanted.format, Options { id: Some(id.to_owned()), ..wanted.options.clone() });
            // The JSON document is made chunk by chunk as the client reads, so its start is
            // cheap (a solution's flux density is computed first: bounded by the size here).
            // Pictures and binary meshes are made whole first: off the async workers. A trip
            // to the blocking pool costs more than a small cached answer itself.
            let inline = format == Format::Json && result.vertices.len() <= INLINE_VERTICES;
            let encoding = if !inline {
                crate::cpu::spawn(move || output::encode(&result, format, &options))
                    .await
                    .map_err(|e| ApiError::Internal(format!("encoding panicked: {e}")))?
            } else {
                output::encode(&result, format, &options)
            };
            let chunks = encoding.into_chunks().map(|c| Ok::<_, Infallible>(Bytes::from(c)));
            let mut response = Body::from_stream(futures_util::stream::iter(chunks)).into_response();
            let media = HeaderValue::from_static(wanted.format.media_type());
            response.headers_mut().insert(header::CONTENT_TYPE, media);
            response
        }
    };
    let h = response.headers_mut();
    if let Some(tag) = etag {
        h.insert(header::ETAG, tag);
    }
    h.insert(header::VARY, HeaderValue::from_static("accept"));
    let cache = match provenance {
        Provenance::Miss => "miss",
        Provenance::Hit => "hit",
        Provenance::Prefix => "prefix",
        Provenance::Partial => "partial",
    };
    h.insert("x-cache", HeaderValue::from_static(cache));
    if let Some(elapsed) = elapsed {
        let timing = format!("engine;dur={:.3}", elapsed.as_secs_f64() * 1e3);
        h.insert("server-timing", HeaderValue::from_str(&timing).expect("ascii"));
    }
    Ok(response)
}

/// Whether `If-None-Match` names `tag` (or `*`): the client has these bytes.
pub(super) fn not_modified(headers: &HeaderMap, tag: &HeaderValue) -> bool {
    let tag = tag.to_str().expect("our tags are ascii");
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.split(',').any(|t| t.trim() == tag || t.trim() == "*"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wanted(uri: &str, accept: Option<&str>) -> Result<Wanted, ApiError> {
        let mut headers = HeaderMap::new();
        if let Some(a) = accept {
            headers.insert(header::ACCEPT, HeaderValue::from_str(a).unwrap());
        }
        Wanted::from_request(&uri.parse().unwrap(), &headers)
    }

    #[test]
    fn the_query_wins_over_accept_and_json_is_the_default() {
        assert_eq!(wanted("/m", None).unwrap().format, Format::Json);
        assert_eq!(wanted("/m", Some("*/*")).unwrap().format, Format::Json);
        assert_eq!(wanted("/m?format=json", Some("image/png")).unwrap().format, Format::Json);
    }

    #[test]
    fn an_unknown_format_is_not_acceptable() {
        assert!(matches!(wanted("/m?format=dxf", None), Err(ApiError::NotAcceptable(n)) if n == "dxf"));
        assert!(matches!(wanted("/m", Some("text/csv")), Err(ApiError::NotAcceptable(_))));
    }

    #[test]
    fn options_out_of_range_are_refused() {
        assert!(matches!(wanted("/m?format=png&size=1", None), Err(ApiError::InvalidRequest(_))));
        assert!(matches!(wanted("/m?colour=red", None), Err(ApiError::InvalidRequest(_))));
        assert_eq!(wanted("/m?format=stl&z_scale=2.5", None).unwrap().options.z_scale, 2.5);
        // Options the format does not take.
        assert!(matches!(wanted("/m?z_scale=2.5", None), Err(ApiError::InvalidRequest(_))));
        assert!(matches!(wanted("/m?format=glb&size=64", None), Err(ApiError::InvalidRequest(_))));
    }

    #[test]
    fn each_form_of_a_result_has_its_own_entity_tag() {
        let tag = |uri| wanted(uri, None).unwrap().etag("ab").to_str().unwrap().to_owned();
        assert_eq!(tag("/m"), "\"ab\"");
        assert_eq!(tag("/m?format=obj&z_scale=2"), "\"ab.obj;z=2\"");
    }
}
