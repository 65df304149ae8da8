//! Refinement by dividing the worst segment.
//!
//! # Usage
//! [`refine`] takes a [`Surface`], the rectangle, [`Params`] and an [`Observer`], and returns
//! the mesh with its [`Stats`]:
//! ```
//! use meshfit::geom::Rect;
//! use meshfit::refine::{refine, Params, StopReason};
//! let f = |x: f64, y: f64| (x * x + y * y).sqrt();
//! let result = refine(&f, Rect::unit(), &Params::new(500).unwrap(), &mut ()).unwrap();
//! assert_eq!(result.mesh.num_vertices(), 500);
//! assert_eq!(result.stats.stop, StopReason::MaxVertices);
//! assert!(result.stats.delaunay);
//! ```
//!
//! # Algorithm
//! Start from S₄ (the corners, diagonal P1P3). Repeatedly take the worst edge (largest
//! |zᵢ − zⱼ|, then longest, then smallest ids) and insert its midpoint M with z = F(M),
//! splitting the one or two triangles beside it. `semi-recursive` then restores the Delaunay
//! property with Lawson flips around M; `recursive` never flips.
//!
//! # Guarantees
//! - Every triangle is strictly counter-clockwise (exact `orient2d`), and the triangles tile
//!   the rectangle; vertex ids are in insertion order and old vertices never move.
//! - `semi-recursive` meshes pass the exact in-circle test on every interior edge; the
//!   reported `delaunay` flag is an independent check of the final mesh.
//! - The same input gives the same mesh bit for bit: one thread, a total order on edges.
//!
//! # Limitations
//! A rounded midpoint of an interior edge can sit a hair off the edge. A split is not made when
//! it would create a non-positive triangle or one smaller than 1e-18 × the rectangle's area,
//! or when the edge is shorter than 1e-9 × the rectangle's diagonal: the edge is *retired*
//! (counted in the stats) and refinement moves on. The floors bound the creep of value-driven
//! splitting toward a point (a cone's tip) or a line (slivers along the boundary), so no run
//! hangs or makes subnormal coordinates.
//!
//! # Stability
//! The order of splits may change between versions of meshfit (the service keys its cache by
//! an engine version); it never changes between two runs of one version.

mod metrics;
mod params;
mod worst_edge;

pub use metrics::{ErrorEstimate, estimate_error, variation};
pub use params::{Criterion, MAX_VERTICES, Method, Params, ParamsError};
pub use worst_edge::{Candidate, WorstEdgeQueue};

use crate::geom::{Mesh, Point, Rect, Vertex};
use crate::source::Surface;
use std::time::{Duration, Instant};

/// Why a refinement stopped. Reaching a budget is an outcome, not an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The mesh has `max_vertices` vertices.
    MaxVertices,
    /// The worst edge's criterion value is at most the tolerance.
    Tolerance,
    /// The time limit passed.
    TimeLimit,
    /// The observer asked to stop.
    Cancelled,
    /// Every remaining edge was retired (too short, or its split would fold a triangle).
    Exhausted,
}

/// A snapshot for progress reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Vertices so far.
    pub vertices: usize,
    /// Triangles so far.
    pub triangles: usize,
    /// The current worst criterion value (V_n for `variation`).
    pub worst: f64,
    /// Time since the refinement started.
    pub elapsed: Duration,
}

/// How often [`Observer::progress`] is called at most.
pub const PROGRESS_INTERVAL: Duration = Duration::from_millis(50);

/// Watches a refinement. Every method has a no-op default and `refine` is generic over the
/// observer, so an unused hook compiles to nothing in the hot loop.
pub trait Observer {
    /// A progress snapshot, at most every [`PROGRESS_INTERVAL`].
    fn progress(&mut self, _progress: &Progress) {}

    /// Checked before every insertion; `true` stops the run with [`StopReason::Cancelled`].
    fn is_cancelled(&self) -> bool {
        false
    }

    /// The edge (a, b) was taken from the queue as the worst, before it is split or retired.
    fn selected(&mut self, _mesh: &Mesh, _a: u32, _b: u32) {}

    /// The edge (a, b) was retired instead of split.
    fn retired(&mut self, _a: u32, _b: u32) {}

    /// Vertex `vertex` was inserted and the mesh is consistent again (flips done).
    fn inserted(&mut self, _mesh: &Mesh, _vertex: u32) {}
}

impl Observer for () {}

/// Counters and the outcome of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Stats {
    /// Vertices n.
    pub vertices: usize,
    /// Triangles (2n − h − 2).
    pub triangles: usize,
    /// V_n = max |zᵢ − zⱼ| over the edges of the final mesh.
    pub variation: f64,
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
    /// Wall-clock time of the run, the one field that differs between identical runs.
    #[serde(rename = "elapsed_ms", serialize_with = "as_millis")]
    pub elapsed: Duration,
}

fn as_millis<S: serde::Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(d.as_secs_f64() * 1e3)
}

/// A finished refinement.
#[derive(Debug, Clone)]
pub struct Refinement {
    /// The mesh.
    pub mesh: Mesh,
    /// What happened.
    pub stats: Stats,
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

/// Edges shorter than this fraction of the rectangle's diagonal are never split.
pub const LENGTH_FLOOR: f64 = 1e-9;

/// No split creates a triangle smaller than this fraction of the rectangle's area.
pub const AREA_FLOOR: f64 = 1e-18;

/// How many insertions pass between looks at the clock.
const CLOCK_EVERY: u64 = 64;

/// Refines S₄ on `rect` until a stop rule of `params` fires. See the [module docs](self).
///
/// # Errors
/// [`RefineError::NonFinite`] when F is not finite at a corner or at a midpoint to insert.
pub fn refine<S, O>(
    surface: &S,
    rect: Rect,
    params: &Params,
    observer: &mut O,
) -> Result<Refinement, RefineError>
where
    S: Surface + ?Sized,
    O: Observer,
{
    let start = Instant::now();
    let mut evaluations = 0u64;
    let mut eval = |p: Point| {
        evaluations += 1;
        let value = surface.eval(p);
        if value.is_finite() { Ok(value) } else { Err(RefineError::NonFinite { point: p, value }) }
    };
    let [p1, p2, p3, p4] = rect.corners();
    let z = [eval(p1)?, eval(p2)?, eval(p3)?, eval(p4)?];
    let n = params.max_vertices();
    let mut mesh = Mesh::with_capacity(rect, z, n);
    // About three edges per vertex are queued over a run.
    let mut queue = WorstEdgeQueue::with_capacity(3 * n.min(1 << 24) + 8);
    for edge in mesh.edges() {
        queue.push(candidate(&mesh, edge.a, edge.b), mesh.vertices());
    }
    let floor_sq = (LENGTH_FLOOR * rect.diagonal()).powi(2);
    let min_area_x2 = 2.0 * AREA_FLOOR * rect.area();
    let semi_recursive = params.method() == Method::SemiRecursive;
    // Scratch stack for Lawson flips, reused so insertions do not allocate.
    let mut stack = Vec::with_capacity(64);
    let (mut flips, mut retired, mut steps) = (0u64, 0u64, 0u64);
    let mut last_report = start;

    let stop = loop {
        if mesh.num_vertices() >= n {
            break StopReason::MaxVertices;
        }
        if observer.is_cancelled() {
            break StopReason::Cancelled;
        }
        steps += 1;
        if steps % CLOCK_EVERY == 0 {
            let now = Instant::now();
            if params.time_limit().is_some_and(|limit| now - start >= limit) {
                break StopReason::TimeLimit;
            }
            if now - last_report >= PROGRESS_INTERVAL {
                last_report = now;
                observer.progress(&Progress {
                    vertices: mesh.num_vertices(),
                    triangles: mesh.num_triangles(),
                    worst: queue.peek().map_or(0.0, |c| c.value),
                    elapsed: now - start,
                });
            }
        }
        let Some(&worst) = queue.peek() else {
            break StopReason::Exhausted;
        };
        let Some(e) = mesh.find_edge(worst.a, worst.b) else {
            // Flipped away since it was queued.
            queue.pop(mesh.vertices());
            continue;
        };
        if params.tolerance().is_some_and(|tolerance| worst.value <= tolerance) {
            break StopReason::Tolerance;
        }
        queue.pop(mesh.vertices());
        observer.selected(&mesh, worst.a, worst.b);
        let m = mesh.point(worst.a).midpoint(mesh.point(worst.b));
        if worst.len_sq(mesh.vertices()) < floor_sq || !mesh.can_split(e, m, min_area_x2) {
            retired += 1;
            observer.retired(worst.a, worst.b);
            continue;
        }
        let z = eval(m)?;
        let split = mesh.split(e, Vertex { x: m.x, y: m.y, z });
        if semi_recursive {
            flips += u64::from(if split.on_edge {
                stack.extend_from_slice(split.link());
                mesh.legalize(&mut stack)
            } else {
                // Flips may now make edges away from the new vertex: queue those here (an
                // edge flipped again later in the same pass goes stale and is skipped).
                stack.extend(split.suspects());
                mesh.legalize_all(&mut stack, |mesh, p, q| {
                    if p != split.vertex && q != split.vertex {
                        queue.push(candidate(mesh, p, q), mesh.vertices());
                    }
                })
            });
        }
        // The other edges this step created end at the new vertex: its halves, the edges to
        // the apexes, and the diagonals of flips around it.
        mesh.for_each_neighbour(split.vertex, |other, _| {
            queue.push(candidate(&mesh, split.vertex, other), mesh.vertices());
        });
        observer.inserted(&mesh, split.vertex);
    };

    let stats = Stats {
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        variation: variation(&mesh),
        flips,
        retired_edges: retired,
        evaluations,
        stop,
        delaunay: mesh.is_delaunay(),
        elapsed: start.elapsed(),
    };
    Ok(Refinement { mesh, stats })
}

/// The queue entry for the edge (p, q) under the variation criterion.
#[inline]
fn candidate(mesh: &Mesh, p: u32, q: u32) -> Candidate {
    Candidate::new((mesh.vertex(p).z - mesh.vertex(q).z).abs(), p, q)
}

#[cfg(test)]
mod tests;
