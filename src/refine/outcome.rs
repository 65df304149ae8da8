//! How a refinement ends: why it stopped, its counters, the mesh it made, or why it failed.

use super::history::Sample;
use super::measures::ErrorEstimate;
use crate::geom::{Mesh, Point};
use std::time::Duration;

/// Why a refinement stopped. Reaching a budget is an outcome, not an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The mesh has `max_vertices` vertices.
    MaxVertices,
    /// The worst criterion value is at most the tolerance.
    Tolerance,
    /// The time limit passed.
    TimeLimit,
    /// The observer asked to stop.
    Cancelled,
    /// Every remaining candidate was retired (too short, or its split would fold a triangle).
    Exhausted,
}

/// Counters and the outcome of a run: the mesher's own, which a finished result reports in
/// its own form (`result::MeshStats`).
#[derive(Debug, Clone, PartialEq)]
pub struct Stats {
    /// Vertices n.
    pub vertices: usize,
    /// Triangles (2n − h − 2).
    pub triangles: usize,
    /// V_n = max |zᵢ − zⱼ| over the edges of the final mesh.
    pub variation: f64,
    /// For the `error` criterion: the largest triangle error estimate e(T) at the end.
    pub max_triangle_error: Option<f64>,
    /// Edge flips made.
    pub flips: u64,
    /// Edges retired instead of split.
    pub retired_edges: u64,
    /// Evaluations of F.
    pub evaluations: u64,
    /// Why the run stopped.
    pub stop: StopReason,
    /// Whether the final mesh passes the exact in-circle test on every interior edge.
    pub delaunay: bool,
    /// With `min_angle`: how many triangles of the final mesh have a smaller angle, their
    /// repair stopped by a size floor, the budget or the tolerance.
    pub below_min_angle: Option<u64>,
    /// V_n and the worst criterion value at vertex counts 4, 6, 8, 12, 16, 24, … and at the
    /// end: the run's convergence.
    pub history: Vec<Sample>,
    /// The final mesh measured against F, when the request asked (`quality`).
    pub quality: Option<ErrorEstimate>,
}

/// A finished refinement.
#[derive(Debug, Clone)]
pub struct Refinement {
    /// The mesh.
    pub mesh: Mesh,
    /// For the `error` criterion: e(T) of each triangle of the final mesh, by triangle index.
    pub triangle_errors: Option<Vec<f64>>,
    /// What happened. Everything in it is the same for every run of one request.
    pub stats: Stats,
    /// Wall-clock time of the run, the one thing that differs between identical runs (kept
    /// out of [`Stats`] so that a result's bytes depend on the request alone).
    pub elapsed: Duration,
}

/// Why a refinement failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RefineError {
    /// F is NaN or infinite at a point the refinement needs.
    #[error("F is not finite at ({x}, {y}): got {value}", x = point.x, y = point.y)]
    NonFinite {
        /// Where.
        point: Point,
        /// What F gave.
        value: f64,
    },
}
