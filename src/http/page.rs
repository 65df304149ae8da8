//! The page for people at `/`: a form, the mesh as it grows, its convergence and downloads.
//!
//! Plain HTML, CSS and JavaScript modules (one per concern: the form, the job, the viewer,
//! the plots, solutions, magnetic devices, downloads, terrain datasets; `main.js` wires them) compiled into the binary, so
//! `cargo run` serves it offline with no build step. It speaks only the public API (`POST /v1/jobs`, the job's events with
//! `?vertices=true`, `GET /v1/jobs/{id}/mesh?format=`), like any other client.

use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::problem::ApiError;

/// The page's files: name, media type, content.
const ASSETS: &[(&str, &str, &str)] = &[
    ("main.js", JS, include_str!("page/main.js")),
    ("state.js", JS, include_str!("page/state.js")),
    ("colours.js", JS, include_str!("page/colours.js")),
    ("form.js", JS, include_str!("page/form.js")),
    ("jobs.js", JS, include_str!("page/jobs.js")),
    ("downloads.js", JS, include_str!("page/downloads.js")),
    ("viewer.js", JS, include_str!("page/viewer.js")),
    ("solutions.js", JS, include_str!("page/solutions.js")),
    ("device.js", JS, include_str!("page/device.js")),
    ("plots.js", JS, include_str!("page/plots.js")),
    ("terrain.js", JS, include_str!("page/terrain.js")),
    ("app.css", "text/css; charset=utf-8", include_str!("page/app.css")),
];

/// The media type of the page's modules.
const JS: &str = "text/javascript; charset=utf-8";

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

#[cfg(test)]
mod tests {
    //! What the page assumes of the server, checked against the server: the formats it offers,
    //! the colour map it draws with, and the PLY layout it reads errors from.

    use super::ASSETS;
    use crate::output::{Format, Options, encode};
    use crate::refine::Criterion;
    use crate::result::testing::sample;
    use std::sync::Arc;

    fn module(name: &str) -> &'static str {
        ASSETS.iter().find(|(n, _, _)| *n == name).unwrap().2
    }

    /// The text between `open` (after `start`) and the next `close`.
    fn between<'a>(text: &'a str, start: &str, open: &str, close: &str) -> &'a str {
        let from = &text[text.find(start).unwrap_or_else(|| panic!("no {start}"))..];
        let from = &from[from.find(open).unwrap() + open.len()..];
        &from[..from.find(close).unwrap()]
    }

    /// A JavaScript string constant's value (escapes `\n` only).
    fn string_const(text: &str, name: &str) -> String {
        between(text, &format!("const {name} = "), "\"", "\"").replace("\\n", "\n")
    }

    #[test]
    fn openapi_names_every_asset_the_server_serves() {
        let doc: serde_yaml_ng::Value = serde_yaml_ng::from_str(include_str!("../../openapi.yaml")).unwrap();
        let listed = &doc["paths"]["/assets/{name}"]["parameters"][0]["schema"]["enum"];
        let listed: Vec<&str> = listed.as_sequence().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
        assert_eq!(listed, ASSETS.iter().map(|(name, _, _)| *name).collect::<Vec<_>>());
    }

    #[test]
    fn the_page_offers_every_format_the_server_encodes_in_its_order() {
        let list = between(module("downloads.js"), "const FORMATS = ", "[", "]");
        let page: Vec<&str> = list.split(',').map(|f| f.trim().trim_matches('"')).collect();
        let server: Vec<&str> = Format::ALL.iter().map(|f| f.name()).collect();
        assert_eq!(page, server);
    }

    #[test]
    fn the_pages_colour_map_is_the_servers_at_its_nine_stops() {
        let stops = between(module("colours.js"), "const VIRIDIS = ", "[", "];");
        let page: Vec<u8> = stops
            .split(|c: char| !c.is_ascii_digit())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(page.len(), 27, "nine RGB stops");
        for (i, stop) in page.chunks(3).enumerate() {
            let server = crate::output::colour::of(i as f64, 0.0, 8.0);
            assert_eq!(stop, server, "stop {i}");
        }
    }

    #[test]
    fn the_ply_layout_the_page_reads_is_the_one_the_server_writes() {
        let page = module("downloads.js");
        let (vertex, face) = (string_const(page, "PLY_VERTEX"), string_const(page, "PLY_FACE"));
        let reader = between(page, "function plyErrors(", "{", "\n}\n");
        assert!(reader.contains("head.includes(PLY_VERTEX)") && reader.contains("head.includes(PLY_FACE)"));
        // The page steps 24 bytes a vertex: three doubles.
        assert_eq!(vertex.matches("property double ").count(), 3);
        let result = Arc::new(sample(200, Criterion::Error));
        assert!(result.indicator().is_some());
        let mut bytes = Vec::new();
        encode(&result, Format::Ply, &Options::default()).write_to(&mut bytes).unwrap();
        let end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap();
        let head = std::str::from_utf8(&bytes[..end]).unwrap();
        assert!(head.contains(&vertex), "{head}");
        assert!(head.contains(&face), "{head}");
        // And the page reads what the server wrote: a face is a count byte, that many ints
        // and the error, right after the vertices.
        let data = &bytes[end + 11..];
        let first_face = &data[24 * result.vertices.len()..];
        let error = f64::from_le_bytes(first_face[13..21].try_into().unwrap());
        assert_eq!((first_face[0], error), (3, result.indicator().unwrap()[0]));
    }
}
