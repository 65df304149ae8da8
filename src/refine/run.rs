//! What every loop shares: the stop rules, progress reports, size floors, the flip stack, the
//! counters, and the one topology step that refinement and replay both take.

use super::angles;
use super::estimator::Field;
use super::floors::Floors;
use super::history::{History, Sample};
use super::observer::{Observer, PROGRESS_INTERVAL, Progress};
use super::outcome::StopReason;
use super::params::{Method, Params};
use crate::geom::{Mesh, Point, Split, Vertex};
use std::time::{Duration, Instant};

/// How many insertions pass between looks at the clock.
pub(super) const CLOCK_EVERY: u64 = 64;

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

/// What both criteria's loops share: the stop rules, progress reports, size floors, the flip
/// stack and the counters.
pub(super) struct Run<'a, O> {
    pub(super) params: &'a Params,
    pub(super) observer: &'a mut O,
    start: Instant,
    /// The observer's paused time when the run started: a run counts only its own pauses.
    paused_before: Duration,
    last_report: Instant,
    steps: u64,
    pub(super) floors: Floors,
    /// Scratch stack for Lawson flips, reused so insertions do not allocate.
    stack: Vec<u32>,
    pub(super) flips: u64,
    retired: u64,
    pub(super) history: History,
}

impl<'a, O: Observer> Run<'a, O> {
    /// A run of `params` that starts now.
    pub(super) fn new(params: &'a Params, observer: &'a mut O, floors: Floors) -> Self {
        let start = Instant::now();
        let paused_before = observer.paused();
        Self {
            params,
            observer,
            start,
            paused_before,
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
    pub(super) fn finish(self, mesh: &Mesh, stop: StopReason, triangle_errors: Option<Vec<f64>>) -> Round {
        let history = self.history.finish(mesh);
        Round { stop, triangle_errors, flips: self.flips, retired: self.retired, history }
    }

    /// The worst value `worst` is about to be compared with the tolerance on `mesh`.
    #[inline]
    pub(super) fn checked(&mut self, mesh: &Mesh, worst: f64) {
        self.observer.checked(worst);
        self.history.check(mesh, worst);
    }

    /// The run's time at `now`, its pauses left out.
    pub(super) fn elapsed_at(&self, now: Instant) -> Duration {
        (now - self.start).saturating_sub(self.observer.paused().saturating_sub(self.paused_before))
    }

    /// The stop rule that fires before the next insertion, if any: the budget, cancellation,
    /// and every [`CLOCK_EVERY`] steps the time limit; progress is reported on the same beat.
    /// `worst` is the current worst criterion value, asked only for a report.
    pub(super) fn stop_before_step(
        &mut self,
        mesh: &Mesh,
        worst: impl FnOnce() -> f64,
    ) -> Option<StopReason> {
        if mesh.num_vertices() >= self.params.max_vertices() {
            return Some(StopReason::MaxVertices);
        }
        if self.observer.is_cancelled() {
            return Some(StopReason::Cancelled);
        }
        self.steps += 1;
        if self.steps.is_multiple_of(CLOCK_EVERY) {
            let now = Instant::now();
            let elapsed = self.elapsed_at(now);
            if self.params.time_limit().is_some_and(|limit| elapsed >= limit) {
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
                        elapsed,
                    },
                );
            }
        }
        None
    }

    /// Starts a step of an edge criterion's loop (`variation`, `curvature`) whose queue's
    /// worst value is `top`: the stop rules, then the check of that value against the
    /// tolerance. `Err` is why the run stops (`Exhausted` with the queue empty).
    pub(super) fn begin_edge_step(&mut self, mesh: &Mesh, top: Option<f64>) -> Result<(), StopReason> {
        if let Some(stop) = self.stop_before_step(mesh, || top.unwrap_or(0.0)) {
            if let Some(worst) = top {
                self.history.ended(mesh.num_vertices(), worst);
            }
            return Err(stop);
        }
        let worst = top.ok_or(StopReason::Exhausted)?;
        self.checked(mesh, worst);
        if self.is_tolerance_met(worst) {
            return Err(StopReason::Tolerance);
        }
        Ok(())
    }

    /// Starts a step of criterion `error`'s loops, whose queue's worst value is `top`: the
    /// stop rules before it, then the check of the worst value against the tolerance. A
    /// pending repair goes first (`Ok(Some(..))`); `Ok(None)` takes the queue's top. With the
    /// queue empty, a repair is checked at 0, and without one the run is exhausted.
    pub(super) fn begin_step(
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
    pub(super) fn is_tolerance_met(&self, worst: f64) -> bool {
        self.params.tolerance().is_some_and(|tolerance| worst <= tolerance)
    }

    /// Splits the edge of half-edge `e` at its midpoint, with z from `field`, and in
    /// semi-recursive mode restores the Delaunay property, telling `on_flip` the half-edge of
    /// each flip's new diagonal. `None` (and an untouched mesh) when the edge is below the
    /// length floor or its split would make a too-small triangle. `predicted` is the
    /// criterion's guess at z there, if it makes one ([`Field::predicted_midpoint`]).
    pub(super) fn split_midpoint<F: Field>(
        &mut self,
        mesh: &mut Mesh,
        field: &mut F,
        e: u32,
        predicted: Option<f64>,
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
        let z = match predicted {
            Some(predicted) => field.predicted_midpoint(a, b, m, predicted)?,
            None => field.midpoint(a, b, m)?,
        };
        Ok(Some(self.insert(mesh, e, Vertex { x: m.x, y: m.y, z }, Placement::OnEdge, on_flip)))
    }

    /// Inserts `v` at half-edge `e` as [`place`] decides, with flips as in
    /// [`Run::split_midpoint`]; `None` (and an untouched mesh) when [`place`] finds no way in.
    pub(super) fn insert_vertex(
        &mut self,
        mesh: &mut Mesh,
        e: u32,
        v: Vertex,
        on_flip: impl FnMut(&Mesh, u32),
    ) -> Option<Split> {
        let (a, b) = (mesh.point(mesh.origin(e)), mesh.point(mesh.dest(e)));
        let Some(placement) = place(mesh, e, v.point(), self.floors.at(a, b).1) else {
            self.retire();
            return None;
        };
        Some(self.insert(mesh, e, v, placement, on_flip))
    }

    /// Counts a step that made no insertion: the worst candidate was left where it is.
    pub(super) fn retire(&mut self) {
        self.retired += 1;
        self.history.retired();
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
pub(super) enum Placement {
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
pub(super) fn place(mesh: &Mesh, e: u32, p: Point, min_area_x2: f64) -> Option<Placement> {
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
pub(super) fn insert(
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
