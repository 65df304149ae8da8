//! ClientSpec: a refinement whose F the caller evaluates, validated.

use super::checks::{Limits, SpecError, budget, build, domain_of, with_sizes};
use crate::api::{ClientJobRequest, OnFailure};
use crate::geom::Rect;
use crate::refine::{Criterion, Method, Params};
use std::time::Duration;

/// The points a batch asks for unless the request says.
pub const DEFAULT_BATCH: u64 = 16;
/// The most points one batch may ask for: a replay runs per batch, not per point, and a
/// batch much larger mostly guesses.
pub const MAX_BATCH: u64 = 1024;
/// The largest budget of a client job: choosing each batch replays the refinement, so a job's
/// engine time grows with the square of its vertices over its batch.
pub const MAX_CLIENT_VERTICES: u64 = 100_000;
/// A batch must be at least a job's budget over this: a job of n vertices in batches of k
/// replays about n²/(2k) insertions, so this bounds them to 5·10⁸ at the largest budget.
pub const VERTICES_PER_BATCH: u64 = 10_000;
/// How long a batch waits for its values unless the request says.
pub const DEFAULT_LEASE: Duration = Duration::from_secs(60);
/// The bounds of a lease: long enough for one round trip, short enough that a lost client's
/// batch comes round again within a day.
pub const LEASE_MS: (u64, u64) = (100, 86_400_000);

/// A client job as the registry runs it.
#[derive(Debug, Clone)]
pub struct ClientSpec {
    /// The rectangle.
    pub rect: Rect,
    /// The engine's parameters: criterion `curvature` or `variation`, no time limit.
    pub params: Params,
    /// The most points a batch asks for.
    pub batch: usize,
    /// How long a batch handed out waits before it is offered again.
    pub lease: Duration,
    /// What a failed point does.
    pub on_failure: OnFailure,
}

impl ClientSpec {
    /// The spec of `request`, checked against `limits`.
    ///
    /// # Errors
    /// A bad domain, budget, tolerance, criterion, batch or lease, naming the field.
    pub fn from_request(request: ClientJobRequest, limits: &Limits) -> Result<Self, SpecError> {
        let rect = match &request.domain {
            Some(d) => domain_of(d)?,
            None => Rect::unit(),
        };
        let problem = |field: &str, detail: String| SpecError::Field { field: field.into(), detail };
        let criterion = request.criterion.unwrap_or(Criterion::Curvature);
        if criterion == Criterion::Error {
            let detail = "a job the client evaluates ranks edges by `curvature` or `variation`, which need F at \
                          the vertices alone; `error` samples F inside every triangle";
            return Err(problem("criterion", detail.into()));
        }
        if request.method == Some(Method::DataDependent) {
            return Err(problem(
                "method",
                "`data-dependent` flips for a grid's samples; use `semi-recursive`".into(),
            ));
        }
        let max_vertices = request.max_vertices.unwrap_or(super::DEFAULT_MAX_VERTICES);
        if max_vertices > MAX_CLIENT_VERTICES {
            return Err(problem(
                "max_vertices",
                format!("a client job has at most {MAX_CLIENT_VERTICES} vertices, got {max_vertices}"),
            ));
        }
        let least = max_vertices.div_ceil(VERTICES_PER_BATCH).max(1);
        let batch = request.batch.unwrap_or(DEFAULT_BATCH.max(least));
        if !(least..=MAX_BATCH).contains(&batch) {
            return Err(problem(
                "batch",
                format!(
                    "must be from {least} to {MAX_BATCH} for {max_vertices} vertices (each batch replays the \
                     refinement), got {batch}"
                ),
            ));
        }
        let lease = match request.lease_ms {
            None => DEFAULT_LEASE,
            Some(ms) if (LEASE_MS.0..=LEASE_MS.1).contains(&ms) => Duration::from_millis(ms),
            Some(ms) => {
                return Err(problem(
                    "lease_ms",
                    format!("must be from {} to {}, got {ms}", LEASE_MS.0, LEASE_MS.1),
                ));
            }
        };
        let sizes = [request.min_size, request.max_size];
        let mut params = with_sizes(budget(Some(max_vertices), limits)?.criterion(criterion), sizes);
        if let Some(method) = request.method {
            params = params.method(method);
        }
        if let Some(tolerance) = request.tolerance {
            params = params.tolerance(tolerance);
        }
        let on_failure = request.on_failure.unwrap_or_default();
        Ok(Self { rect, params: build(params, limits)?, batch: batch as usize, lease, on_failure })
    }
}
