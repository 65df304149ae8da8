//! The mesh document: `{"id": ..., "vertices": [[x, y, z], ...], "triangles": [[i, j, k], ...],
//! "stats": {...}}`, with the result's main field under its key before the stats (a
//! magnetostatic solution's `"flux_density": [[Bx, By], ...]` per triangle).
//!
//! Numbers are written by serde_json's shortest round-trip formatting, so a reader gets back
//! the exact f64 values. Vertices are in insertion order, triangles counter-clockwise. The
//! document has no line breaks, so it also fits in one server-sent event's `data` line.

use super::{Encoded, Options, Part};
use crate::result::{MeshStats, Quality, Role, RunResult};
use serde::Serialize;
use std::io::{self, Write};
use std::sync::Arc;

/// The document, with `"id"` first when the options carry one (the API's).
pub fn encode(result: &Arc<RunResult>, options: &Options) -> Encoded {
    let mut head = b"{".to_vec();
    if let Some(id) = &options.id {
        head.extend_from_slice(b"\"id\":");
        serde_json::to_writer(&mut head, id).expect("a string serializes");
        head.push(b',');
    }
    head.extend_from_slice(b"\"vertices\":[");
    let mut tail = b",\"stats\":".to_vec();
    serde_json::to_writer(&mut tail, &result.stats).expect("stats serialize");
    tail.push(b'}');
    let (r, s) = (result.clone(), result.clone());
    let mut parts = vec![
        Part::Bytes(head),
        Part::rows(result.vertices.len(), move |i, out| {
            let v = r.vertices[i];
            if i > 0 {
                out.push(b',');
            }
            serde_json::to_writer(out, &[v.x, v.y, v.z]).expect("finite numbers serialize");
        }),
        Part::Bytes(b"],\"triangles\":[".to_vec()),
        Part::rows(result.triangles.len(), move |i, out| {
            if i > 0 {
                out.push(b',');
            }
            serde_json::to_writer(out, &s.triangles[i]).expect("integers serialize");
        }),
        Part::Bytes(b"]".to_vec()),
    ];
    // The document stays small: of the fields, it carries the one the run is about.
    if let Some(f) = result.with_role(Role::Main) {
        let field = &result.fields[f];
        let mut key = b",".to_vec();
        serde_json::to_writer(&mut key, &field.key).expect("a string serializes");
        key.extend_from_slice(b":[");
        parts.push(Part::Bytes(key));
        let r = result.clone();
        parts.push(Part::rows(field.len(), move |i, out| {
            if i > 0 {
                out.push(b',');
            }
            match r.fields[f].value(i) {
                [v] => serde_json::to_writer(out, v),
                value => serde_json::to_writer(out, value),
            }
            .expect("finite numbers serialize");
        }));
        parts.push(Part::Bytes(b"]".to_vec()));
    }
    parts.push(Part::Bytes(tail));
    Encoded::new(parts)
}

/// The stats-only document: `{"stats": {...}, "error": {...}, "elapsed_ms": ...}`.
#[derive(Serialize)]
pub struct StatsDocument<'a> {
    /// The run's counters and outcome.
    pub stats: &'a MeshStats,
    /// The E_n estimate.
    pub error: Quality,
    /// The refinement's wall-clock time (not the estimate's), as a job's status reports it.
    pub elapsed_ms: f64,
}

/// Writes the stats-only document to `out`.
///
/// # Errors
/// Whatever writing to `out` returns.
pub fn write_stats(document: &StatsDocument<'_>, out: &mut impl Write) -> io::Result<()> {
    serde_json::to_writer_pretty(&mut *out, document).map_err(io::Error::from)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::Summary;
    use crate::result::testing::sample;

    #[test]
    fn the_document_parses_back_to_the_exact_result() {
        let result = Arc::new(sample(500, Criterion::Error));
        let options = Options { id: Some("abc".into()), ..Options::default() };
        let doc: serde_json::Value = serde_json::from_slice(&encode(&result, &options).to_vec()).unwrap();
        assert_eq!(doc["id"], "abc");
        let vertices = doc["vertices"].as_array().unwrap();
        assert_eq!(vertices.len(), result.vertices.len());
        for (got, v) in vertices.iter().zip(&result.vertices) {
            let xyz: [f64; 3] = serde_json::from_value(got.clone()).unwrap();
            assert_eq!(xyz, [v.x, v.y, v.z]);
        }
        let triangles: Vec<[u32; 3]> = serde_json::from_value(doc["triangles"].clone()).unwrap();
        assert_eq!(triangles, result.triangles);
        let stats: Summary = serde_json::from_value(doc["stats"].clone()).unwrap();
        assert_eq!(stats, result.stats);
        assert!(doc.get("flux_density").is_none(), "a mesh has no field");
        assert!(doc["stats"].get("elapsed_ms").is_none(), "the body depends on the request alone");
    }

    #[test]
    fn without_an_id_the_document_starts_with_the_vertices() {
        let result = Arc::new(sample(4, Criterion::Variation));
        let text = String::from_utf8(encode(&result, &Options::default()).to_vec()).unwrap();
        assert!(text.starts_with("{\"vertices\":[[-1.0,0.0,"), "{text}");
        assert!(!text.contains('\n'));
    }
}
