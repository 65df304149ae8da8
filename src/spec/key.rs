//! The job id: a SHA-256 of the spec's canonical encoding.
//!
//! Every field is written in a fixed order with floats by their exact bits, after defaults are
//! filled in, so key order, `1` versus `1.0` and omitted defaults never make a new entry.
//! std's `DefaultHasher` is not used: its docs say its output may change between releases.

use super::job::{JobSpec, Work};
use super::solution::{Function, SolveSpec};
use crate::solve::Shape;
use crate::source::Source;
use sha2::{Digest, Sha256};

/// Bumped whenever the engine may produce a different mesh for the same request, so that a
/// cache (in memory or on disk) never serves a mesh the current engine would not make.
pub const ENGINE_VERSION: &str = "meshfit-engine-8";

/// A job's id, and the id of its family: the requests that differ from it only in budget,
/// tolerance or time limit, whose runs are prefixes of one another.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JobKeys {
    /// The job id.
    pub id: String,
    /// The family id.
    pub family: String,
}

/// The lowercase hex SHA-256 id of `spec`.
pub fn job_id(spec: &JobSpec) -> String {
    job_keys(spec).id
}

/// The id and family id of `spec`, from one pass over its fields (a grid is hashed once).
pub fn job_keys(spec: &JobSpec) -> JobKeys {
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
    // The limit the client named, not the one in force: server settings never change ids.
    let ms = spec.requested_time_limit.map_or(Vec::new(), |t| (t.as_millis() as u64).to_le_bytes().to_vec());
    let spec = match &spec.work {
        Work::Mesh(mesh) => mesh,
        Work::Solve(solve) => {
            field(&mut h, "kind", b"solution");
            solution_fields(&mut h, solve, field);
            field(&mut h, "time_limit_ms", &ms);
            // No family: a smaller solution is not a prefix of a larger one.
            let id = format!("{:x}", h.finalize());
            return JobKeys { family: id.clone(), id };
        }
    };
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
    field(&mut h, "method", p.method().to_string().as_bytes());
    field(&mut h, "criterion", p.criterion().to_string().as_bytes());
    field(&mut h, "quality", &[u8::from(spec.quality)]);
    field(&mut h, "min_angle", &p.min_angle().map_or(Vec::new(), |a| a.to_bits().to_le_bytes().to_vec()));
    let mut family = h.clone();
    field(&mut family, "family", &[]);
    field(&mut h, "max_vertices", &(p.max_vertices() as u64).to_le_bytes());
    field(&mut h, "tolerance", &p.tolerance().map_or(Vec::new(), |t| t.to_bits().to_le_bytes().to_vec()));
    field(&mut h, "time_limit_ms", &ms);
    JobKeys { id: format!("{:x}", h.finalize()), family: format!("{:x}", family.finalize()) }
}

/// The fields of a boundary value problem, in a fixed order, numbers by their bits.
fn solution_fields(h: &mut Sha256, spec: &SolveSpec, field: fn(&mut Sha256, &str, &[u8])) {
    let bits = |v: f64| v.to_bits().to_le_bytes();
    let optional = |v: Option<f64>| v.map_or(Vec::new(), |v| bits(v).to_vec());
    let coef = |h: &mut Sha256, name: &str, c: Option<&Function>| match c {
        None => field(h, name, &[]),
        Some(Function::Constant(v)) => field(h, name, &[&[0u8][..], &bits(*v)].concat()),
        Some(Function::Expression(e)) => field(h, name, &[&[1u8][..], e.text().as_bytes()].concat()),
    };
    field(h, "physics", format!("{:?}", spec.physics).as_bytes());
    let d = spec.domain;
    field(h, "domain", &[d.x0(), d.x1(), d.y0(), d.y1()].map(bits).concat());
    coef(h, "k", Some(&spec.k));
    coef(h, "f", Some(&spec.f));
    coef(h, "g", Some(&spec.g));
    coef(h, "exact", spec.exact.as_ref());
    field(h, "regions", &(spec.regions.len() as u64).to_le_bytes());
    let b = spec.boundary;
    field(h, "boundary", format!("{:?}", [b.left, b.right, b.bottom, b.top]).as_bytes());
    for (r, table) in spec.regions.iter().zip(&spec.tables) {
        let shape = match &r.shape {
            Shape::Rect(rect) => {
                [&[0u8][..], &[rect.x0(), rect.x1(), rect.y0(), rect.y1()].map(bits).concat()].concat()
            }
            Shape::Polygon(polygon) => {
                let points = polygon.corners();
                let corners = points.iter().flat_map(|p| [bits(p.x), bits(p.y)]).collect::<Vec<_>>().concat();
                [&[1u8][..], &(points.len() as u64).to_le_bytes(), &corners].concat()
            }
        };
        let table =
            table.iter().flatten().flat_map(|&[h, b]| [bits(h), bits(b)]).collect::<Vec<_>>().concat();
        let source = r.source.map_or(Vec::new(), |[x, y]| [bits(x), bits(y)].concat());
        field(h, "region", &[shape, optional(r.k), optional(r.f)].concat());
        field(h, "material", &[(table.len() as u64).to_le_bytes().to_vec(), table, source].concat());
    }
    let s = &spec.settings;
    field(h, "method", s.method.to_string().as_bytes());
    field(h, "criterion", format!("{:?}", s.indicator).as_bytes());
    field(h, "growth", &bits(s.growth));
    field(h, "max_vertices", &(s.max_vertices as u64).to_le_bytes());
    field(h, "tolerance", &optional(s.tolerance));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::JobRequest;
    use crate::output::{self, Format, Options};
    use crate::refine::refine;
    use crate::result::RunResult;
    use crate::spec::Limits;
    use std::sync::Arc;
    use std::time::Duration;

    fn limits(job_time_limit: Duration) -> Limits {
        Limits { max_vertices: 1 << 20, max_grid_points: 1 << 20, max_expression_len: 100, job_time_limit }
    }

    fn spec(body: &str, limits: &Limits) -> JobSpec {
        let request: JobRequest = serde_json::from_str(body).unwrap();
        JobSpec::from_request(request, limits).unwrap()
    }

    #[test]
    fn budget_tolerance_and_time_limit_change_the_id_but_not_the_family() {
        let l = limits(Duration::from_secs(60));
        let base = job_keys(&spec(r#"{"function": "x*y", "max_vertices": 500}"#, &l));
        for other in [
            r#"{"function": "x*y", "max_vertices": 400}"#,
            r#"{"function": "x*y", "max_vertices": 500, "tolerance": 0.1}"#,
            r#"{"function": "x*y", "max_vertices": 500, "time_limit_ms": 5}"#,
        ] {
            let keys = job_keys(&spec(other, &l));
            assert_ne!(keys.id, base.id, "{other}");
            assert_eq!(keys.family, base.family, "{other}");
        }
        for other in [
            r#"{"function": "x*y", "method": "recursive"}"#,
            r#"{"function": "x*y", "criterion": "variation"}"#,
            r#"{"function": "y*x"}"#,
            r#"{"function": "x*y", "domain": {"x": [0, 2], "y": [0, 1]}}"#,
        ] {
            assert_ne!(job_keys(&spec(other, &l)).family, base.family, "{other}");
        }
    }

    #[test]
    fn the_server_time_limit_never_changes_an_id() {
        let body = r#"{"function": "x*y", "max_vertices": 500}"#;
        let (short, long) = (limits(Duration::from_secs(1)), limits(Duration::from_secs(600)));
        assert_eq!(job_id(&spec(body, &short)), job_id(&spec(body, &long)));
        let named = r#"{"function": "x*y", "max_vertices": 500, "time_limit_ms": 1000}"#;
        assert_ne!(job_id(&spec(body, &short)), job_id(&spec(named, &short)), "a named limit is asked for");
    }

    /// The id and the SHA-256 of the mesh document of `body`, under this engine version.
    fn id_and_hash(body: &str) -> (String, String) {
        let spec = spec(body, &limits(Duration::from_secs(60)));
        let id = job_id(&spec);
        let mesh = spec.mesh().unwrap();
        let refinement = refine(&*mesh.source, mesh.domain, &mesh.params, &mut ()).unwrap();
        let result = Arc::new(RunResult::from(refinement));
        let options = Options { id: Some(id.clone()), ..Options::default() };
        let body = output::encode(&result, Format::Json, &options).to_vec();
        (id, format!("{:x}", Sha256::digest(&body)))
    }

    /// Requests' ids and the SHA-256 of their mesh documents, pinned with the engine version:
    /// a change that alters meshes fails here until it bumps [`ENGINE_VERSION`] on purpose
    /// (then update the figures with what this test prints). One expression, and one grid,
    /// whose meshes take another path (vertices on its nodes).
    #[test]
    fn pinned_requests_give_the_pinned_ids_and_bytes_under_this_engine_version() {
        let expression = r#"{"function": "x*x*y - y*y + 0.5*x", "max_vertices": 2000, "domain": {"x": [-1, 2], "y": [0, 1]}}"#;
        let values: Vec<String> =
            (0..40 * 30).map(|k| format!("{}", (k % 40) * (k / 40) % 17 + (k % 7) * 3)).collect();
        let grid = format!(
            r#"{{"grid": {{"nx": 40, "ny": 30, "values": [{}]}}, "max_vertices": 300, "domain": {{"x": [0, 2], "y": [-1, 0.5]}}}}"#,
            values.join(",")
        );
        let pinned = [
            (
                "meshfit-engine-8",
                "9487d6a4aa7e1dc42bceb113b644110319fb030c98abd7f8502436a0817346ba",
                "d5cf40ce1a49739b4f881aed41c15cef6033beb5ddfc0ddbeb52b8c161614537",
            ),
            (
                "meshfit-engine-8",
                "e9a23f9d9824db513a698da8ff8cf984ae6a51423b360551fcf5a46d8cc2197a",
                "5fd7076637917d2f6d3a1a3e5ef862f236fe4394babd2699879a31205d165bcd",
            ),
        ];
        for (body, pinned) in [expression, &grid].into_iter().zip(pinned) {
            let (id, hash) = id_and_hash(body);
            assert_eq!((ENGINE_VERSION, id.as_str(), hash.as_str()), pinned);
        }
    }
}
