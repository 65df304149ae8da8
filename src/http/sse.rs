//! Server-sent events written as bytes.
//!
//! A stream ends with a light `result` event: the job's status and the links to its mesh in
//! each format. Asked for inline (`?inline=mesh`), the event carries the mesh document
//! instead; axum's `Event` would hold it in one buffer per client, a copy of a 10^6-vertex
//! mesh for every one. Here the inline event is the shared result encoded chunk by chunk as
//! the client reads it, so twenty stalled readers hold twenty chunks, not twenty meshes. The
//! JSON document has no line breaks, so it is one `data:` line.

use crate::api::{ProgressEvent, ResultEvent};
use crate::geom::Vertex;
use crate::output::{self, Format, Options};
use crate::result::RunResult;
use axum::body::Body;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use futures_util::{Stream, StreamExt};
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

/// How long a stream may stay silent before a comment line keeps proxies from closing it.
pub const KEEP_ALIVE: Duration = Duration::from_secs(15);

/// The comment sent when nothing else has been for [`KEEP_ALIVE`].
pub fn keep_alive() -> Bytes {
    Bytes::from_static(b":\n\n")
}

/// A `progress` event with id `seq`; with `points`, the vertices from index `first` on, as
/// `"first_point"` and a flat `"points": [x, y, z, x, y, z, …]`.
pub fn progress(seq: u64, p: &ProgressEvent, points: Option<(usize, &[Vertex])>) -> Bytes {
    #[derive(serde::Serialize)]
    struct WithPoints<'a> {
        #[serde(flatten)]
        progress: &'a ProgressEvent,
        first_point: usize,
        points: Vec<f64>,
    }
    let data = match points {
        None => serde_json::to_string(p),
        Some((first, vertices)) => serde_json::to_string(&WithPoints {
            progress: p,
            first_point: first,
            points: vertices.iter().flat_map(|v| [v.x, v.y, v.z]).collect(),
        }),
    };
    let data = data.expect("progress serializes");
    Bytes::from(format!("event: progress\nid: {seq}\ndata: {data}\n\n"))
}

/// An `error` event carrying a problem document.
pub fn error(id: u64, problem: &serde_json::Value) -> Bytes {
    Bytes::from(format!("event: error\nid: {id}\ndata: {problem}\n\n"))
}

/// The light `result` event: the finished job's status and where its mesh is.
pub fn finished(id: u64, event: &ResultEvent) -> Bytes {
    let data = serde_json::to_string(event).expect("a status serializes");
    Bytes::from(format!("event: result\nid: {id}\ndata: {data}\n\n"))
}

/// A `result` event carrying the JSON document of `result`, in chunks made as they are read
/// (`?inline=mesh`).
pub fn result(id: u64, job: &str, result: &Arc<RunResult>) -> impl Iterator<Item = Bytes> + Send + use<> {
    let options = Options { id: Some(job.to_owned()), ..Options::default() };
    let head = Bytes::from(format!("event: result\nid: {id}\ndata: "));
    let document = output::encode(result, Format::Json, &options).into_chunks().map(Bytes::from);
    std::iter::once(head).chain(document).chain(std::iter::once(Bytes::from_static(b"\n\n")))
}

/// The response for a stream of event bytes.
pub fn response(events: impl Stream<Item = Bytes> + Send + 'static) -> Response {
    let mut response = Body::from_stream(events.map(Ok::<_, Infallible>)).into_response();
    let h = response.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static("text/event-stream"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    response
}
