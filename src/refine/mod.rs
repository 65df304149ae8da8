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
//! Start from S₄ (the corners, diagonal P1P3). Repeatedly take the worst edge and insert its
//! midpoint M with z = F(M), splitting the one or two triangles beside it. `semi-recursive`
//! then restores the Delaunay property with Lawson flips around M; `recursive` never flips.
//! `data-dependent` (a grid with criterion `error`) is `semi-recursive` until the last
//! insertion, then flips the worst triangles' edges where that lowers the largest error.
//!
//! The criterion says which edge is worst. [`Criterion::Variation`] is the paper's: the
//! largest |zᵢ − zⱼ|, then the longest, then the smallest ids. With [`Criterion::Error`] (the
//! default) every triangle carries a sampled error e(T) = max |F − F_n|, and the worst
//! triangle's worst long edge is bisected (`semi-recursive`) or its longest-edge propagation
//! path is followed (`recursive`, Rivara), which bounds angles from below.
//!
//! # Guarantees
//! - Every triangle is strictly counter-clockwise (exact `orient2d`), and the triangles tile
//!   the rectangle; vertex ids are in insertion order and old vertices never move.
//! - `semi-recursive` meshes pass the exact in-circle test on every interior edge; the
//!   reported `delaunay` flag is an independent check of the final mesh (false for a
//!   `data-dependent` mesh once it flipped for its error).
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

mod angles;
mod bands;
mod error_criterion;
mod history;
mod metrics;
mod nodes;
mod params;
pub mod trace;
mod variation;
mod worst_edge;
mod worst_triangle;

use history::History;
pub use history::Sample;
pub use metrics::{ErrorEstimate, dense_max_error, estimate_error, variation};
pub use params::{Criterion, MAX_MIN_ANGLE, MAX_VERTICES, Method, Params, ParamsError};
pub use worst_edge::{Candidate, WorstEdgeQueue};

use crate::geom::{Mesh, Point, Rect, Split, Vertex};
use crate::source::Surface;
use std::time::{Duration, Instant};

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
    /// A boundary value problem's Newton iteration did not converge on the latest mesh; the
    /// result is the last round that did.
    NotConverged,
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
    /// A nonlinear solve's Newton steps and final relative residual.
    pub newton: Option<(u32, f64)>,
}

/// How often [`Observer::progress`] is called at most.
pub const PROGRESS_INTERVAL: Duration = Duration::from_millis(50);

/// Watches a refinement. Every method has a no-op default and `refine` is generic over the
/// observer, so an unused hook compiles to nothing in the hot loop.
pub trait Observer {
    /// A progress snapshot of `mesh`, at most every [`PROGRESS_INTERVAL`].
    fn progress(&mut self, _mesh: &Mesh, _progress: &Progress) {}

    /// Checked before every insertion; `true` stops the run with [`StopReason::Cancelled`].
    fn is_cancelled(&self) -> bool {
        false
    }

    /// The edge (a, b) was chosen to split, before it is split or retired: the worst edge for
    /// `variation`, the edge serving the worst triangle for `error`.
    fn selected(&mut self, _mesh: &Mesh, _a: u32, _b: u32) {}

    /// The edge (a, b) was retired instead of split (for `error`, with its triangle).
    fn retired(&mut self, _a: u32, _b: u32) {}

    /// Vertex `vertex` was inserted and the mesh is consistent again (flips done).
    fn inserted(&mut self, _mesh: &Mesh, _vertex: u32) {}

    /// The run puts its vertices on grid nodes rather than edge midpoints (criterion `error`
    /// on a grid, `semi-recursive`); called before [`Observer::started`].
    fn on_nodes(&mut self) {}

    /// The loop is about to start, after `evaluations` evaluations of F (the corners, and for
    /// `error` the first two triangles' samples).
    fn started(&mut self, _evaluations: u64) {}

    /// The worst criterion value `worst` is about to be compared with the tolerance.
    fn checked(&mut self, _worst: f64) {}

    /// Criterion `error`: triangle `t` now has the estimate e(T) = `error`.
    fn estimated(&mut self, _t: u32, _error: f64) {}

    /// A step that passed the tolerance check ended: half-edge `split` was split (its id
    /// before the split), or with `None` an edge was retired; F has now been evaluated
    /// `evaluations` times in all.
    fn stepped(&mut self, _split: Option<u32>, _evaluations: u64) {}
}

impl Observer for () {}

/// Counters and the outcome of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Stats {
    /// Vertices n.
    pub vertices: usize,
    /// Triangles (2n − h − 2).
    pub triangles: usize,
    /// V_n = max |zᵢ − zⱼ| over the edges of the final mesh.
    pub variation: f64,
    /// For the `error` criterion: the largest triangle error estimate e(T) at the end.
    #[serde(skip_serializing_if = "Option::is_none")]
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
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub below_min_angle: Option<u64>,
    /// V_n and the worst criterion value at vertex counts 4, 6, 8, 12, 16, 24, … and at the
    /// end: the run's convergence.
    pub history: Vec<Sample>,
    /// The final mesh measured against F, when the request asked (`quality`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
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

/// Edges shorter than this fraction of the rectangle's diagonal are never split.
pub const LENGTH_FLOOR: f64 = 1e-9;

/// No split creates a triangle smaller than this fraction of the rectangle's area.
pub const AREA_FLOOR: f64 = 1e-18;

/// How many insertions pass between looks at the clock.
const CLOCK_EVERY: u64 = 64;

/// Refines S₄ on `rect` until a stop rule of `params` fires. See the [module docs](self).
///
/// # Errors
/// [`RefineError::NonFinite`] when F is not finite at a corner or at a point the refinement
/// needs (a midpoint to insert, or a sample of the error criterion).
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
    let mut sampler = Sampler { surface, evaluations: 0, batch: error_criterion::Batch::default() };
    let [p1, p2, p3, p4] = rect.corners();
    let z = [sampler.eval(p1)?, sampler.eval(p2)?, sampler.eval(p3)?, sampler.eval(p4)?];
    let mut mesh = Mesh::with_capacity(rect, z, params.max_vertices());
    let floors = Floors::of_rect(rect);
    let round = match surface.grid() {
        Some(grid) if params.criterion() == Criterion::Error && params.method() != Method::Recursive => {
            let mut run = Run::new(params, observer, floors);
            let (stop, errors) = nodes::refine(&mut mesh, grid, &mut run, &mut sampler.evaluations);
            run.finish(&mesh, stop, Some(errors))
        }
        _ => resume(&mut mesh, &mut sampler, params, floors, observer)?,
    };
    let max_triangle_error =
        round.triangle_errors.as_ref().map(|e: &Vec<f64>| e.iter().copied().fold(0.0, f64::max));
    let stats = Stats {
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        // The history's final sample walked the final mesh (or knew V_n): not again here.
        variation: History::final_variation(&round.history),
        max_triangle_error,
        flips: round.flips,
        retired_edges: round.retired,
        evaluations: sampler.evaluations,
        stop: round.stop,
        delaunay: mesh.is_delaunay(),
        below_min_angle: params.min_angle().map(|degrees| angles::count_below(&mesh, degrees)),
        history: round.history,
        quality: None,
    };
    Ok(Refinement { mesh, triangle_errors: round.triangle_errors, stats, elapsed: start.elapsed() })
}

/// Where a refinement gets the value of each new vertex: F at the midpoint for a mesh, the
/// interpolated value between the solves of a boundary value problem.
pub(crate) trait Field {
    /// Why a value could not be had.
    type Error;

    /// z of the midpoint `m` of the edge from `a` to `b`.
    fn midpoint(&mut self, a: Vertex, b: Vertex, m: Point) -> Result<f64, Self::Error>;

    /// Evaluations of F so far, for the observer.
    fn evaluations(&self) -> u64 {
        0
    }
}

/// How criterion `error` ranks triangles: F's sampled error for a mesh, a residual indicator
/// for a boundary value problem.
pub(crate) trait Estimator: Field {
    /// Whether `semi-recursive` too bisects the end of the worst triangle's longest-edge path
    /// (then flips), instead of the worst of its long edges.
    const LONGEST_EDGE_PATH: bool = false;

    /// The estimate of triangle `t` and its part on each edge (by half-edge position);
    /// `known` holds an edge's part where a fresh neighbour already measured it.
    fn estimate(
        &mut self,
        mesh: &Mesh,
        t: u32,
        known: [Option<f64>; 3],
    ) -> Result<(f64, [f64; 3]), Self::Error>;

    /// Whether [`Estimator::estimate_many`] beats estimating a step's triangles one by one.
    fn batches(&self) -> bool {
        false
    }

    /// [`Estimator::estimate`] for each triangle of `ts` (sorted), in order, into `out`.
    /// `known[i]` is what fresh triangles outside `ts` know of `ts[i]`'s edges; an edge two
    /// triangles of `ts` share is measured by the first and lent to the second. Estimators that
    /// share work across triangles (one batch of samples) override it, with the same results.
    fn estimate_many(
        &mut self,
        mesh: &Mesh,
        ts: &[u32],
        known: &[[Option<f64>; 3]],
        out: &mut Vec<(f64, [f64; 3])>,
    ) -> Result<(), Self::Error> {
        for (i, &t) in ts.iter().enumerate() {
            let estimate = self.estimate(mesh, t, error_criterion::lend(mesh, ts, i, known[i], out))?;
            out.push(estimate);
        }
        Ok(())
    }

    /// A step rewrote the triangles `touched`; called before any of them is estimated again.
    fn rewritten(&mut self, _mesh: &Mesh, _touched: &[u32]) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// The smallest edge a refinement splits and the smallest triangle it makes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Floors {
    /// Fixed fractions of the rectangle ([`LENGTH_FLOOR`], [`AREA_FLOOR`]): a mesh never
    /// needs finer, and the floors stop value-driven splitting from creeping toward a point.
    Rect {
        /// Squared length floor.
        length_sq: f64,
        /// Floor on twice a new triangle's area.
        area_x2: f64,
    },
    /// What floating point resolves around the edge: [`RESOLUTION`] of its coordinates'
    /// magnitude, and never below [`ABSOLUTE_FLOOR`]. A solution's singular point may need
    /// vertices many orders of magnitude closer to it than the rectangle's size.
    Resolution,
}

/// The relative length floor of a solution's mesh: about 10^6 units in the last place of the
/// edge's coordinates, so a singular point gets vertices as close as floating point resolves.
pub const RESOLUTION: f64 = 1.0 / (1u64 << 32) as f64;

/// The absolute length floor of a solution's mesh: the exact predicates multiply up to
/// four coordinate differences, and 1e-60⁴ stays far above the subnormal range.
pub const ABSOLUTE_FLOOR: f64 = 1e-60;

impl Floors {
    /// The floors of a mesh of `rect`.
    pub(crate) fn of_rect(rect: Rect) -> Self {
        Self::Rect {
            length_sq: (LENGTH_FLOOR * rect.diagonal()).powi(2),
            area_x2: 2.0 * AREA_FLOOR * rect.area(),
        }
    }

    /// (squared length floor, floor on twice a new triangle's area) for the edge a–b.
    #[inline]
    fn at(&self, a: Point, b: Point) -> (f64, f64) {
        match *self {
            Self::Rect { length_sq, area_x2 } => (length_sq, area_x2),
            Self::Resolution => {
                let scale = a.x.abs().max(a.y.abs()).max(b.x.abs()).max(b.y.abs());
                let floor = (RESOLUTION * scale).max(ABSOLUTE_FLOOR);
                (floor * floor, floor * floor)
            }
        }
    }
}

/// What [`resume`] did.
#[derive(Debug, Clone)]
pub(crate) struct Round {
    /// Why it stopped.
    pub stop: StopReason,
    /// For criterion `error`: the estimate of every triangle at the end, by index.
    pub triangle_errors: Option<Vec<f64>>,
    /// Edge flips made.
    pub flips: u64,
    /// Edges retired instead of split.
    pub retired: u64,
    /// The convergence samples, ending with the final mesh's.
    pub history: Vec<Sample>,
}

/// Refines `mesh` as it stands until a stop rule of `params` fires (the time limit counts
/// from this call): the loop of [`refine`], open to values that change between rounds. New
/// vertices take their z from `estimator` as a [`Field`]; criterion `error` ranks triangles by
/// its estimates, `variation` by the vertices' z.
pub(crate) fn resume<E: Estimator, O: Observer>(
    mesh: &mut Mesh,
    estimator: &mut E,
    params: &Params,
    floors: Floors,
    observer: &mut O,
) -> Result<Round, E::Error> {
    let mut run = Run::new(params, observer, floors);
    let (stop, triangle_errors) = match params.criterion() {
        Criterion::Variation => (variation::refine(mesh, estimator, &mut run)?, None),
        Criterion::Error => {
            let (stop, errors) = error_criterion::refine(mesh, estimator, &mut run)?;
            (stop, Some(errors))
        }
    };
    Ok(run.finish(mesh, stop, triangle_errors))
}

/// F with a count of evaluations; a non-finite value is an error naming the point.
struct Sampler<'s, S: ?Sized> {
    surface: &'s S,
    evaluations: u64,
    /// The error criterion's samples of a step, kept so that steps do not allocate.
    batch: error_criterion::Batch,
}

impl<S: Surface + ?Sized> Sampler<'_, S> {
    #[inline]
    fn eval(&mut self, p: Point) -> Result<f64, RefineError> {
        self.evaluations += 1;
        let value = self.surface.eval(p);
        if value.is_finite() { Ok(value) } else { Err(RefineError::NonFinite { point: p, value }) }
    }

    /// F at each point into `out`; the first non-finite value is the error.
    #[inline]
    fn eval_many(&mut self, points: &[Point], out: &mut [f64]) -> Result<(), RefineError> {
        self.evaluations += points.len() as u64;
        self.surface.eval_many(points, out);
        match out.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => Err(RefineError::NonFinite { point: points[i], value: out[i] }),
        }
    }
}

impl<S: Surface + ?Sized> Field for Sampler<'_, S> {
    type Error = RefineError;

    #[inline]
    fn midpoint(&mut self, _a: Vertex, _b: Vertex, m: Point) -> Result<f64, RefineError> {
        self.eval(m)
    }

    fn evaluations(&self) -> u64 {
        self.evaluations
    }
}

/// What both criteria's loops share: the stop rules, progress reports, size floors, the flip
/// stack and the counters.
struct Run<'a, O> {
    params: &'a Params,
    observer: &'a mut O,
    start: Instant,
    last_report: Instant,
    steps: u64,
    floors: Floors,
    /// Scratch stack for Lawson flips, reused so insertions do not allocate.
    stack: Vec<u32>,
    flips: u64,
    retired: u64,
    history: History,
}

impl<'a, O: Observer> Run<'a, O> {
    /// A run of `params` that starts now.
    fn new(params: &'a Params, observer: &'a mut O, floors: Floors) -> Self {
        let start = Instant::now();
        Self {
            params,
            observer,
            start,
            last_report: start,
            steps: 0,
            floors,
            stack: Vec::with_capacity(64),
            flips: 0,
            retired: 0,
            history: History::new(params.criterion(), params.method()),
        }
    }

    /// What the run did, once it stopped with `stop` on `mesh`.
    fn finish(self, mesh: &Mesh, stop: StopReason, triangle_errors: Option<Vec<f64>>) -> Round {
        let history = self.history.finish(mesh);
        Round { stop, triangle_errors, flips: self.flips, retired: self.retired, history }
    }

    /// The worst value `worst` is about to be compared with the tolerance on `mesh`.
    #[inline]
    fn checked(&mut self, mesh: &Mesh, worst: f64) {
        self.observer.checked(worst);
        self.history.check(mesh, worst);
    }

    /// The stop rule that fires before the next insertion, if any: the budget, cancellation,
    /// and every [`CLOCK_EVERY`] steps the time limit; progress is reported on the same beat.
    /// `worst` is the current worst criterion value, asked only for a report.
    fn stop_before_step(&mut self, mesh: &Mesh, worst: impl FnOnce() -> f64) -> Option<StopReason> {
        if mesh.num_vertices() >= self.params.max_vertices() {
            return Some(StopReason::MaxVertices);
        }
        if self.observer.is_cancelled() {
            return Some(StopReason::Cancelled);
        }
        self.steps += 1;
        if self.steps.is_multiple_of(CLOCK_EVERY) {
            let now = Instant::now();
            if self.params.time_limit().is_some_and(|limit| now - self.start >= limit) {
                return Some(StopReason::TimeLimit);
            }
            if now - self.last_report >= PROGRESS_INTERVAL {
                self.last_report = now;
                self.observer.progress(
                    mesh,
                    &Progress {
                        vertices: mesh.num_vertices(),
                        triangles: mesh.num_triangles(),
                        worst: worst(),
                        elapsed: now - self.start,
                        newton: None,
                    },
                );
            }
        }
        None
    }

    /// Starts a step of criterion `error`'s loops, whose queue's worst value is `top`: the
    /// stop rules before it, then the check of the worst value against the tolerance. A
    /// pending repair goes first (`Ok(Some(..))`); `Ok(None)` takes the queue's top. With the
    /// queue empty, a repair is checked at 0, and without one the run is exhausted.
    fn begin_step(
        &mut self,
        mesh: &Mesh,
        top: Option<f64>,
        repairs: &mut angles::Repairs,
    ) -> Result<Option<(u32, angles::Repair)>, StopReason> {
        if let Some(stop) = self.stop_before_step(mesh, || top.unwrap_or(0.0)) {
            return Err(stop);
        }
        let repair = repairs.next(mesh);
        let worst = match (top, repair) {
            (Some(top), _) => top,
            (None, Some(_)) => 0.0,
            (None, None) => return Err(StopReason::Exhausted),
        };
        self.checked(mesh, worst);
        if self.is_tolerance_met(worst) {
            return Err(StopReason::Tolerance);
        }
        Ok(repair)
    }

    /// Whether the tolerance stops the run at this worst value.
    fn is_tolerance_met(&self, worst: f64) -> bool {
        self.params.tolerance().is_some_and(|tolerance| worst <= tolerance)
    }

    /// Splits the edge of half-edge `e` at its midpoint, with z from `field`, and in
    /// semi-recursive mode restores the Delaunay property, telling `on_flip` the half-edge of
    /// each flip's new diagonal. `None` (and an untouched mesh) when the edge is below the
    /// length floor or its split would make a too-small triangle.
    fn split_midpoint<F: Field>(
        &mut self,
        mesh: &mut Mesh,
        field: &mut F,
        e: u32,
        on_flip: impl FnMut(&Mesh, u32),
    ) -> Result<Option<Split>, F::Error> {
        let (a, b) = (mesh.vertex(mesh.origin(e)), mesh.vertex(mesh.dest(e)));
        let m = a.point().midpoint(b.point());
        let (floor_sq, min_area_x2) = self.floors.at(a.point(), b.point());
        if a.point().distance_sq(b.point()) < floor_sq || !mesh.can_split(e, m, min_area_x2) {
            self.retired += 1;
            self.history.retired();
            return Ok(None);
        }
        let z = field.midpoint(a, b, m)?;
        Ok(Some(self.insert(mesh, e, Vertex { x: m.x, y: m.y, z }, Placement::OnEdge, on_flip)))
    }

    /// Inserts `v` at half-edge `e` as [`place`] decides, with flips as in
    /// [`Run::split_midpoint`]; `None` (and an untouched mesh) when [`place`] finds no way in.
    fn insert_vertex(
        &mut self,
        mesh: &mut Mesh,
        e: u32,
        v: Vertex,
        on_flip: impl FnMut(&Mesh, u32),
    ) -> Option<Split> {
        let (a, b) = (mesh.point(mesh.origin(e)), mesh.point(mesh.dest(e)));
        let Some(placement) = place(mesh, e, v.point(), self.floors.at(a, b).1) else {
            self.retired += 1;
            self.history.retired();
            return None;
        };
        Some(self.insert(mesh, e, v, placement, on_flip))
    }

    fn insert(
        &mut self,
        mesh: &mut Mesh,
        e: u32,
        v: Vertex,
        placement: Placement,
        mut on_flip: impl FnMut(&Mesh, u32),
    ) -> Split {
        let (split, flips) =
            insert(mesh, e, v, placement, self.params.method(), &mut self.stack, &mut on_flip);
        self.flips += u64::from(flips);
        split
    }
}

/// How a new vertex goes in at a half-edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Placement {
    /// On the half-edge's edge (or a hair off it): the one or two triangles beside it split.
    OnEdge,
    /// Strictly inside the half-edge's triangle, which splits in three.
    Inside,
}

/// How a vertex at `p` goes in at half-edge `e`: e's midpoint on its edge, as in the paper;
/// any other point inside e's triangle when every new triangle clears `min_area_x2`, otherwise
/// on e's edge (`p` on the edge, or near it on either side). `None` when the split that would
/// be made does not clear the floor. Refinement and replay both ask here, so a traced step
/// is redone as it was made.
fn place(mesh: &Mesh, e: u32, p: Point, min_area_x2: f64) -> Option<Placement> {
    let is_midpoint = p == mesh.point(mesh.origin(e)).midpoint(mesh.point(mesh.dest(e)));
    if !is_midpoint && mesh.can_insert_inside(e / 3, p, min_area_x2) {
        Some(Placement::Inside)
    } else {
        mesh.can_split(e, p, min_area_x2).then_some(Placement::OnEdge)
    }
}

/// Inserts `v` at half-edge `e` (on its edge, or inside its triangle) and, with
/// `semi-recursive`, restores the Delaunay property by Lawson flips, telling `on_flip` the
/// half-edge of each new diagonal. Returns the split and the number of flips. The one
/// topology step of every loop: refinement's, and a replay's of a traced run.
fn insert(
    mesh: &mut Mesh,
    e: u32,
    v: Vertex,
    placement: Placement,
    method: Method,
    stack: &mut Vec<u32>,
    on_flip: impl FnMut(&Mesh, u32),
) -> (Split, u32) {
    let split = match placement {
        Placement::OnEdge => mesh.split(e, v),
        Placement::Inside => mesh.insert_inside(e / 3, v),
    };
    // `data-dependent` is `semi-recursive` until its last insertion.
    let flips = match method {
        Method::Recursive => 0,
        Method::SemiRecursive | Method::DataDependent if split.exact => {
            stack.extend_from_slice(split.link());
            mesh.legalize(stack, on_flip)
        }
        Method::SemiRecursive | Method::DataDependent => {
            stack.extend(split.suspects());
            mesh.legalize_all(stack, on_flip)
        }
    };
    (split, flips)
}

#[cfg(test)]
mod tests;
