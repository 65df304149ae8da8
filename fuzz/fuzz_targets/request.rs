//! A request body, decoded and validated as the service does, and run when it is accepted.
//!
//! The bytes are a JSON body for `POST /v1/meshes` (`JobRequest`, `JobSpec::from_request`)
//! and for `POST /v1/solutions` (`SolveRequest`, `JobSpec::from_solve_request`); when they
//! hold the line `--grid--`, the part before it is the `request` part of a multipart upload
//! and the part after it the `grid` file (`JobSpec::from_upload`). JSON goes through a copy
//! of the service's `parse_json` (`meshfit::http::parse_json`), with small `Limits`.
//!
//! Checks that nothing panics; that every refusal renders as a problem document with a 4xx
//! status; that an accepted spec is within the limits and hashes to the same 64-hex-digit id
//! twice; and, by running it as the worker does (refinement traced, or the adaptive solve),
//! that an accepted request runs without panicking, stays within its budget, and gives a
//! mesh that passes `check_invariants` (and, for a semi-recursive mesh, `is_delaunay`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use meshfit::api::{JobRequest, SolveRequest};
use meshfit::http::parse_json;
use meshfit::http::problem::ApiError;
use meshfit::jobs::JobError;
use meshfit::spec::{JobSpec, Limits, Work, job_keys};
use meshfit::refine::trace::Recorder;
use meshfit::refine::{Method, refine};
use meshfit::result::RunResult;
use meshfit::source::Source;
use std::time::Duration;

/// Small enough that every accepted request runs in well under a second.
const LIMITS: Limits = Limits {
    max_vertices: 2000,
    max_grid_points: 10_000,
    max_expression_len: 4096,
    job_time_limit: Duration::from_millis(200),
};

/// Splits an upload's `request` part from its `grid` part.
const GRID_PART: &[u8] = b"\n--grid--\n";

/// Bodies above this are skipped: the limits refuse their contents anyway.
const MAX_BODY: usize = 256 * 1024;

/// A refusal must be a client error with a complete problem document.
fn check_refusal(e: &ApiError) {
    let doc = e.to_json();
    let status = doc["status"].as_u64().expect("a problem has a numeric status");
    assert!((400..500).contains(&status), "a refused request answers {status}: {doc}");
    assert!(doc["type"].as_str().is_some_and(|t| t.starts_with("/problems/")), "{doc}");
    assert!(doc["detail"].is_string() && doc["title"].is_string(), "{doc}");
    let _ = doc.to_string();
}

/// A run's failure (F not finite, an invalid coefficient) is reported as a problem too.
fn check_failure(e: JobError) {
    let _ = e.to_string();
    let doc = ApiError::from(e).to_json();
    assert!(doc["status"].is_u64(), "{doc}");
    let _ = doc.to_string();
}

fn settle(spec: Result<JobSpec, ApiError>) {
    let spec = match spec {
        Ok(spec) => spec,
        Err(e) => return check_refusal(&e),
    };
    let keys = job_keys(&spec);
    assert_eq!(keys.id.len(), 64, "id {}", keys.id);
    assert!(keys.id.bytes().all(|b| b.is_ascii_hexdigit()), "id {}", keys.id);
    assert_eq!(job_keys(&spec), keys, "the id of one spec changed");
    match &spec.work {
        Work::Mesh(mesh) => {
            let params = &mesh.params;
            assert!(params.max_vertices() <= LIMITS.max_vertices);
            assert!(params.time_limit().is_some_and(|t| t <= LIMITS.job_time_limit));
            if let Source::Grid(g) = &*mesh.source {
                assert!(g.nx() >= 2 && g.ny() >= 2 && g.nx() * g.ny() <= LIMITS.max_grid_points);
                assert_eq!(g.rect(), mesh.domain, "the grid is not spread over the domain");
            }
            let mut quiet = ();
            let mut recorder = Recorder::new(&mut quiet, params);
            let run = match refine(&*mesh.source, mesh.domain, params, &mut recorder) {
                Ok(run) => run,
                Err(e) => return check_failure(JobError::Refine(e)),
            };
            let _trace = recorder.finish(run.stats.stop);
            if let Err(e) = run.mesh.check_invariants() {
                panic!("accepted mesh request gave a broken mesh: {e}");
            }
            assert!(run.mesh.num_vertices() <= params.max_vertices());
            if params.method() == Method::SemiRecursive {
                assert!(run.stats.delaunay, "semi-recursive mesh is not Delaunay");
            }
            let result = RunResult::from(run);
            assert!(result.vertices.iter().all(|v| v.z.is_finite()));
        }
        Work::Solve(solve) => {
            assert!(solve.settings.max_vertices <= LIMITS.max_vertices);
            let adapted = match solve.solve(&mut ()) {
                Ok(a) => a,
                Err(e) => return check_failure(JobError::Solve(e)),
            };
            if let Err(e) = adapted.mesh.check_invariants() {
                panic!("accepted boundary value problem gave a broken mesh: {e}");
            }
            assert!(adapted.mesh.num_vertices() <= solve.settings.max_vertices);
            let _ = adapted.into_result(solve.physics);
        }
    }
}

fuzz_target!(|data: &[u8]| {
    if data.len() > MAX_BODY {
        return;
    }
    let split = data.windows(GRID_PART.len()).position(|w| w == GRID_PART);
    match split {
        Some(at) => {
            let (request, grid) = (&data[..at], &data[at + GRID_PART.len()..]);
            // The service takes `{}` for a missing request part; an empty one is sent as is.
            let spec = parse_json::<JobRequest>(request)
                .and_then(|r| JobSpec::from_upload(r, grid, &LIMITS).map_err(ApiError::from));
            settle(spec);
        }
        None => {
            let mesh = parse_json::<JobRequest>(data)
                .and_then(|r| JobSpec::from_request(r, &LIMITS).map_err(ApiError::from));
            settle(mesh);
            let solution = parse_json::<SolveRequest>(data)
                .and_then(|r| JobSpec::from_solve_request(r, &LIMITS).map_err(ApiError::from));
            settle(solution);
        }
    }
});
