//! The job id: a SHA-256 of the spec's canonical encoding.
//!
//! Every field is written in a fixed order with floats by their exact bits, after defaults are
//! filled in, so key order, `1` versus `1.0` and omitted defaults never make a new entry.
//! std's `DefaultHasher` is not used: its docs say its output may change between releases.

use super::spec::JobSpec;
use crate::source::Source;
use sha2::{Digest, Sha256};

/// Bumped whenever the engine may produce a different mesh for the same request, so that a
/// cache (in memory or on disk) never serves a mesh the current engine would not make.
pub const ENGINE_VERSION: &str = "meshfit-engine-4";

/// The lowercase hex SHA-256 id of `spec`.
pub fn job_id(spec: &JobSpec) -> String {
    let mut h = Sha256::new();
    // Each field is (name length, name, value length, value): no two specs share an encoding.
    fn header(h: &mut Sha256, name: &str, len: usize) {
        h.update((name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        h.update((len as u64).to_le_bytes());
    }
    fn field(h: &mut Sha256, name: &str, bytes: &[u8]) {
        header(h, name, bytes.len());
        h.update(bytes);
    }
    field(&mut h, "engine", ENGINE_VERSION.as_bytes());
    match &*spec.source {
        Source::Expression(e) => field(&mut h, "function", e.text().as_bytes()),
        Source::Grid(g) => {
            field(&mut h, "grid.nx", &(g.nx() as u64).to_le_bytes());
            field(&mut h, "grid.ny", &(g.ny() as u64).to_le_bytes());
            header(&mut h, "grid.values", 8 * g.nx() * g.ny());
            // Streamed row by row: a large grid is never copied whole.
            let mut row = Vec::with_capacity(8 * g.nx());
            for j in 0..g.ny() {
                row.clear();
                row.extend((0..g.nx()).flat_map(|i| g.value(i, j).to_bits().to_le_bytes()));
                h.update(&row);
            }
        }
    }
    let d = spec.domain;
    for (name, v) in [("domain.a", d.x0()), ("domain.b", d.x1()), ("domain.c", d.y0()), ("domain.d", d.y1())]
    {
        field(&mut h, name, &v.to_bits().to_le_bytes());
    }
    let p = &spec.params;
    field(&mut h, "max_vertices", &(p.max_vertices() as u64).to_le_bytes());
    field(&mut h, "tolerance", &p.tolerance().map_or(Vec::new(), |t| t.to_bits().to_le_bytes().to_vec()));
    field(&mut h, "method", p.method().to_string().as_bytes());
    field(&mut h, "criterion", p.criterion().to_string().as_bytes());
    let ms = p.time_limit().map_or(0, |t| t.as_millis() as u64);
    field(&mut h, "time_limit_ms", &ms.to_le_bytes());
    format!("{:x}", h.finalize())
}
