//! The job id: a SHA-256 of the spec's canonical encoding ([`canonical`]), so key order,
//! `1` versus `1.0` and omitted defaults never make a new entry. std's `DefaultHasher` is not
//! used: its docs say its output may change between releases.

use super::canonical::{self, Sink};
use super::job::JobSpec;
use sha2::{Digest, Sha256};

/// A job's id, and the id of its family: the requests that differ from it only in budget,
/// tolerance or time limit, whose runs are prefixes of one another.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JobKeys {
    /// The job id.
    pub id: String,
    /// The family id.
    pub family: String,
}

/// Whether `id` has the shape of the ids this service makes (a SHA-256 in hex): anything
/// else names no job and no file.
pub fn is_hex_id(id: &str) -> bool {
    id.len() == 64 && id.bytes().all(|b| b.is_ascii_hexdigit())
}

/// The lowercase hex SHA-256 id of `spec`.
pub fn job_id(spec: &JobSpec) -> String {
    job_keys(spec).id
}

/// The id and family id of `spec`: SHA-256 of its canonical encoding, and of the part a
/// family shares, hashed as it is written (a grid is never copied whole).
pub fn job_keys(spec: &JobSpec) -> JobKeys {
    let mut hashes = Hashes { id: Sha256::new(), family: None };
    canonical::write(spec, &mut hashes);
    let id = format!("{:x}", hashes.id.finalize());
    // No family for a solution: a smaller one is not a prefix of a larger one.
    let family = hashes.family.map_or_else(|| id.clone(), |f| format!("{:x}", f.finalize()));
    JobKeys { id, family }
}

/// The id's hash, and the family's once its fields have all gone by.
struct Hashes {
    id: Sha256,
    family: Option<Sha256>,
}

impl Sink for Hashes {
    fn put(&mut self, bytes: &[u8]) {
        self.id.update(bytes);
    }

    fn family(&mut self) {
        let mut family = self.id.clone();
        // Then a field named "family" with no value: no spec's own encoding goes on like this.
        family.update((b"family".len() as u64).to_le_bytes());
        family.update(b"family");
        family.update(0u64.to_le_bytes());
        self.family = Some(family);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::JobRequest;
    use crate::output::{self, Format, Options};
    use crate::refine::refine;
    use crate::result::RunResult;
    use crate::spec::ENGINE_VERSION;
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
                "meshfit-engine-9",
                "4ba16a9cd9116a2d4273abb9de3599d5e6405eb35aa61c2fb7944d918235a395",
                "d61f2fc7f01e0d6893fc1cef3a420fac75e36cce039190d12a9e47e7ce8127ac",
            ),
            (
                "meshfit-engine-9",
                "29e3bdf7cbdd21433c50a0dcf8fe9a72e77e16c4413a1d14e33d6ddd22a1772f",
                "4858b85eb116756d67fce07c5861c8413617604012d98fe5de12159ea9bf3fea",
            ),
        ];
        for (body, pinned) in [expression, &grid].into_iter().zip(pinned) {
            let (id, hash) = id_and_hash(body);
            assert_eq!((ENGINE_VERSION, id.as_str(), hash.as_str()), pinned);
        }
    }
}
