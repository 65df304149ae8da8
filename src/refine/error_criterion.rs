//! The error criterion: split an edge of the triangle whose sampled error
//! e(T) = max |F − F_n| is largest.
//!
//! Every vertex is still the midpoint of a mesh edge and old vertices never move, as in the
//! paper; what changes is which edge: the one that serves the worst-approximated triangle.
//! `semi-recursive` bisects that triangle's worst edge among its longer ones (see
//! [`split_edge`]) and flips; `recursive` follows the longest-edge propagation path (Rivara)
//! and bisects its terminal edge, one midpoint per step, which keeps angles bounded away from
//! zero. (On a grid, `semi-recursive` puts its vertices on the grid's nodes instead: see
//! [`super::nodes`].)

use super::angles::{Encroachment, Repair, Repairs, longest_edge, terminal_edge};
use super::estimator::{Estimator, lend, lender};
use super::measures::{LATTICE, lattice_point};
use super::nodes::worst_node;
use super::observer::Observer;
use super::outcome::{RefineError, StopReason};
use super::params::Method;
use super::run::Run;
use super::sampler::{Batch, Sampler};
use super::worst_triangle::{Entry, WorstTriangleQueue};
use crate::geom::{Mesh, NONE, Point, Vertex};
use crate::source::Surface;

/// What is known of one triangle slot: 32 bytes, aligned, so one cache line holds it whole.
#[derive(Debug, Clone, Copy)]
#[repr(align(32))]
struct Slot {
    /// e(T); NaN from the moment a step rewrites the triangle until it is estimated again
    /// (an estimate is finite), so that the slot's edges are not lent out meanwhile.
    error: f64,
    /// The error on each of its edges' lattice points, by half-edge position. Both triangles
    /// of an edge sample the same points (the weights of the third corner are zero and IEEE
    /// addition commutes), so a neighbour may take these instead of evaluating F again.
    edges: [f64; 3],
}

impl Slot {
    const STALE: Self = Self { error: f64::NAN, edges: [0.0; 3] };

    /// Whether `error` and `edges` describe the triangle now in the slot.
    fn is_fresh(&self) -> bool {
        !self.error.is_nan()
    }
}

/// Triangle errors and the queue over them.
struct Estimates {
    queue: WorstTriangleQueue,
    slots: Vec<Slot>,
    next_seq: u32,
    /// What fresh neighbours know of a step's triangles, and the step's estimates; kept so
    /// that steps do not allocate.
    known: Vec<[Option<f64>; 3]>,
    out: Vec<(f64, [f64; 3])>,
}

impl Estimates {
    /// Triangle `t`'s slot, made (stale) if the triangle is new.
    fn slot_mut(&mut self, t: u32) -> &mut Slot {
        let t = t as usize;
        if self.slots.len() <= t {
            self.slots.resize(t + 1, Slot::STALE);
        }
        &mut self.slots[t]
    }

    /// Marks triangle `t` as rewritten, so neighbours stop borrowing its edge errors.
    fn invalidate(&mut self, t: u32) {
        *self.slot_mut(t) = Slot::STALE;
    }

    /// The error on the edge of half-edge `e` as a fresh triangle on its far side knows it.
    fn known_edge_error(&self, mesh: &Mesh, e: u32) -> Option<f64> {
        let f = mesh.twin(e);
        let slot = self.slots.get((f / 3) as usize).filter(|_| f != NONE)?;
        slot.is_fresh().then_some(slot.edges[(f % 3) as usize])
    }

    /// [`Estimates::known_edge_error`] for each edge of triangle `t`.
    fn known_edges(&self, mesh: &Mesh, t: u32) -> [Option<f64>; 3] {
        [0, 1, 2].map(|k| self.known_edge_error(mesh, 3 * t + k))
    }

    /// Estimates the triangles `ts` (sorted, all stale) and queues them, in order.
    fn estimate<E: Estimator, O: Observer>(
        &mut self,
        mesh: &Mesh,
        estimator: &mut E,
        ts: &[u32],
        observer: &mut O,
    ) -> Result<(), E::Error> {
        if !estimator.batches() {
            for &t in ts {
                let (error, edges) = estimator.estimate(mesh, t, self.known_edges(mesh, t))?;
                self.set(t, error, edges, observer);
            }
            return Ok(());
        }
        let (mut known, mut out) = (std::mem::take(&mut self.known), std::mem::take(&mut self.out));
        known.clear();
        known.extend(ts.iter().map(|&t| self.known_edges(mesh, t)));
        out.clear();
        let estimated = estimator.estimate_many(mesh, ts, &known, &mut out);
        for (&t, &(error, edges)) in ts.iter().zip(&out) {
            self.set(t, error, edges, observer);
        }
        (self.known, self.out) = (known, out);
        estimated
    }

    fn set<O: Observer>(&mut self, t: u32, error: f64, edges: [f64; 3], observer: &mut O) {
        observer.estimated(t, error);
        let seq = self.next_seq;
        self.next_seq += 1;
        debug_assert!(error.is_finite(), "e(T) = {error}");
        *self.slot_mut(t) = Slot { error, edges };
        self.queue.set(Entry { error, seq, t });
    }
}

/// Refines `mesh` worst triangle first until a stop rule fires. Returns why it stopped and
/// the estimate of every triangle at that point, by triangle index.
pub(super) fn refine<E: Estimator, O: Observer>(
    mesh: &mut Mesh,
    estimator: &mut E,
    run: &mut Run<'_, O>,
) -> Result<(StopReason, Vec<f64>), E::Error> {
    let n = run.params.max_vertices();
    // Sized for the budget (capped for huge ones), so the run does not copy them as they grow.
    let room = n.min(1 << 24);
    let mut estimates = Estimates {
        queue: WorstTriangleQueue::with_capacity(2 * room),
        slots: Vec::with_capacity(2 * room),
        next_seq: 0,
        known: Vec::new(),
        out: Vec::new(),
    };
    for t in 0..mesh.num_triangles() as u32 {
        estimates.invalidate(t);
    }
    // In chunks, so that a resumed mesh's first estimates do not hold every sample at once.
    let n = mesh.num_triangles() as u32;
    let mut chunk = Vec::with_capacity(64);
    for start in (0..n).step_by(64) {
        chunk.clear();
        chunk.extend(start..n.min(start + 64));
        estimates.estimate(mesh, estimator, &chunk, run.observer)?;
    }
    run.observer.started(estimator.evaluations());
    let recursive = run.params.method() == Method::Recursive;
    let encroachment = if recursive { Encroachment::Never } else { Encroachment::Lens };
    let mut repairs = Repairs::new(encroachment, run.params.min_angle());
    // Triangles a step rewrote, re-estimated after it; reused so steps do not allocate.
    let mut touched: Vec<u32> = Vec::with_capacity(32);
    let stop = loop {
        let repair = match run.begin_step(mesh, estimates.queue.peek().map(|e| e.error), &mut repairs) {
            Ok(repair) => repair,
            Err(stop) => break stop,
        };
        let (e, popped) = match repair {
            Some((_, Repair::Encroached(h))) => (h, None),
            Some((t, Repair::Skinny)) => (terminal_edge(mesh, t), None),
            None => {
                let worst = estimates.queue.pop().expect("the queue's top");
                let e = if recursive || E::LONGEST_EDGE_PATH {
                    terminal_edge(mesh, worst.t)
                } else {
                    split_edge(mesh, worst.t, &estimates.slots[worst.t as usize])
                };
                (e, Some(worst))
            }
        };
        run.observer.selected(mesh, mesh.origin(e), mesh.dest(e));
        touched.clear();
        let split = run.split_midpoint(mesh, estimator, e, None, |mesh, d| {
            touched.extend([d / 3, mesh.twin(d) / 3]);
        })?;
        let Some(split) = split else {
            // The triangle stays as it is, out of the queue (or, for a repair, unrepaired).
            run.observer.retired(mesh.origin(e), mesh.dest(e));
            run.observer.stepped(None, estimator.evaluations());
            continue;
        };
        touched.extend(split.link().iter().map(|&h| h / 3));
        touched.sort_unstable();
        touched.dedup();
        for &t in &touched {
            estimates.invalidate(t);
        }
        estimator.rewritten(mesh, &touched)?;
        estimates.estimate(mesh, estimator, &touched, run.observer)?;
        if let Some(worst) = popped.filter(|w| !touched.contains(&w.t)) {
            // Rivara bisected a neighbour first: the worst triangle is still there, unchanged.
            estimates.queue.set(worst);
        }
        repairs.look_at(&touched);
        run.observer.inserted(mesh, split.vertex);
        run.observer.stepped(Some(e), estimator.evaluations());
    };
    let errors = estimates.slots[..mesh.num_triangles()].iter().map(|s| s.error).collect();
    Ok((stop, errors))
}

/// How long, relative to the longest edge and in squared length, an edge must be for
/// `semi-recursive` to bisect it in the longest edge's place (√0.6 ≈ 0.77 of the length).
///
/// Bisecting where the sampled error is (greedy insertion puts its point there) lowers E_n at
/// 10^4 vertices by 3–9 % on Franke, peaks, exp(x + y) and the bump, which takes all seven
/// quality functions to or below pydelatin's (docs/quality.md); anything from 0.55 to 0.65
/// does. Without a floor, short edges are split again and again into slivers (angles of
/// 1e-14° on Franke, with 12× the error).
const SPLIT_LENGTH_SQ_RATIO: f64 = 0.6;

/// The edge `semi-recursive` bisects in triangle `t`, whose estimate is `slot`: when the
/// triangle's worst sample lies on an edge, the edge with the largest sampled error among
/// those with at least [`SPLIT_LENGTH_SQ_RATIO`] of the longest's squared length; otherwise
/// (the worst sample is inside, or a grid node) the longest edge. Ties keep the longest.
fn split_edge(mesh: &Mesh, t: u32, slot: &Slot) -> u32 {
    let longest = longest_edge(mesh, t);
    if slot.edges.iter().all(|&e| e < slot.error) {
        return longest;
    }
    let floor = SPLIT_LENGTH_SQ_RATIO * mesh.len_sq(longest);
    let error = |e: u32| slot.edges[(e % 3) as usize];
    (3 * t..3 * t + 3)
        .fold(longest, |best, e| if error(e) > error(best) && mesh.len_sq(e) >= floor { e } else { best })
}

/// A mesh's estimate: F's sampled error.
impl<S: Surface + ?Sized> Estimator for Sampler<'_, S> {
    #[inline]
    fn estimate(
        &mut self,
        mesh: &Mesh,
        t: u32,
        known: [Option<f64>; 3],
    ) -> Result<(f64, [f64; 3]), RefineError> {
        triangle_error(mesh, t, self, known)
    }

    /// A grid's samples are loads from its rows, as cheap one by one as in a batch, and the
    /// batch's bookkeeping cost 2.7% more instructions on the Jacksboro DEM.
    fn batches(&self) -> bool {
        self.surface.grid().is_none()
    }

    fn estimate_many(
        &mut self,
        mesh: &Mesh,
        ts: &[u32],
        known: &[[Option<f64>; 3]],
        out: &mut Vec<(f64, [f64; 3])>,
    ) -> Result<(), RefineError> {
        triangles_error(mesh, ts, known, self, out)
    }
}

/// The lattice points of a triangle that are still to sample: a triangle's points, the
/// interpolant there and where each one's error goes (as in [`Batch`]).
struct Lattice {
    points: [Point; LATTICE.len()],
    linear: [f64; LATTICE.len()],
    owner: [u8; LATTICE.len()],
    count: usize,
}

impl Lattice {
    /// The points of the triangle with `corners` that lie inside it or on an edge not yet
    /// `measured`.
    #[inline]
    fn of(corners: &[Vertex; 3], measured: [bool; 3]) -> Self {
        let mut lattice = Self {
            points: [Point::new(0.0, 0.0); LATTICE.len()],
            linear: [0.0; LATTICE.len()],
            owner: [0; LATTICE.len()],
            count: 0,
        };
        for (index, weights) in LATTICE.into_iter().enumerate() {
            // LATTICE lists the points of edge 0 (a→b), 1 (b→c), 2 (c→a), then the interior.
            let place = (index / 3).min(3);
            if place < 3 && measured[place] {
                continue;
            }
            let k = lattice.count;
            (lattice.points[k], lattice.linear[k]) = lattice_point(corners, weights);
            lattice.owner[k] = place as u8;
            lattice.count += 1;
        }
        lattice
    }
}

/// e(T) over a triangle's lattice and its error on each edge, from F at its points still to
/// sample (`values`, with `linear` and `owner` as in [`Batch`]) and the edges `known`.
#[inline]
fn lattice_error(values: &[f64], linear: &[f64], owner: &[u8], known: [Option<f64>; 3]) -> (f64, [f64; 3]) {
    let mut edges = known.map(|e| e.unwrap_or(0.0));
    let mut interior = 0.0f64;
    for ((v, l), &place) in values.iter().zip(linear).zip(owner) {
        let err = (v - l).abs();
        match place {
            3 => interior = interior.max(err),
            k => edges[k as usize] = edges[k as usize].max(err),
        }
    }
    (edges.iter().fold(interior, |m, &e| m.max(e)), edges)
}

/// e(T) = max |F(s) − F_n(s)| over the lattice points s of triangle `t`, and for a grid also
/// over the grid nodes inside it (nodes alone would miss the small triangles that hold none).
/// Returns e(T) and the error on each edge's points; an edge a fresh neighbour has already
/// sampled (`known`) is not sampled again.
fn triangle_error<S: Surface + ?Sized>(
    mesh: &Mesh,
    t: u32,
    sampler: &mut Sampler<'_, S>,
    known: [Option<f64>; 3],
) -> Result<(f64, [f64; 3]), RefineError> {
    let corners = mesh.triangle(t as usize).map(|v| mesh.vertex(v));
    let lattice = Lattice::of(&corners, known.map(|e| e.is_some()));
    let mut values = [0.0; LATTICE.len()];
    let values = &mut values[..lattice.count];
    // One batch: a compiled expression decodes each operation once for all the points.
    sampler.eval_many(&lattice.points[..lattice.count], values)?;
    let (mut error, edges) = lattice_error(values, &lattice.linear, &lattice.owner, known);
    if let Some(grid) = sampler.surface.grid() {
        error = worst_node(grid, corners.map(|v| in_grid(grid, v)), corners.map(|v| v.z), error).error;
    }
    Ok((error, edges))
}

/// [`triangle_error`] for each triangle of `ts` (sorted) into `out`, in order, with the
/// points of all of them sampled as one batch. An edge that `known` gives, or that an earlier
/// triangle of `ts` samples, is not sampled again. The bits are those of estimating the
/// triangles one by one.
fn triangles_error<S: Surface + ?Sized>(
    mesh: &Mesh,
    ts: &[u32],
    known: &[[Option<f64>; 3]],
    sampler: &mut Sampler<'_, S>,
    out: &mut Vec<(f64, [f64; 3])>,
) -> Result<(), RefineError> {
    let mut batch = std::mem::take(&mut sampler.batch);
    let Batch { points, linear, owner, values, counts } = &mut batch;
    points.clear();
    linear.clear();
    owner.clear();
    counts.clear();
    for (i, &t) in ts.iter().enumerate() {
        let corners = mesh.triangle(t as usize).map(|v| mesh.vertex(v));
        let measured = |k: usize| known[i][k].is_some() || lender(mesh, ts, i, k).is_some();
        let lattice = Lattice::of(&corners, [measured(0), measured(1), measured(2)]);
        points.extend_from_slice(&lattice.points[..lattice.count]);
        linear.extend_from_slice(&lattice.linear[..lattice.count]);
        owner.extend_from_slice(&lattice.owner[..lattice.count]);
        counts.push(lattice.count as u8);
    }
    values.resize(points.len(), 0.0);
    // One batch: a compiled expression decodes each operation once for all the points. (On
    // an error the run ends, and the buffers with it.)
    sampler.eval_many(points, values)?;
    let mut next = 0;
    for (i, &count) in counts.iter().enumerate() {
        let range = next..next + usize::from(count);
        let known = lend(mesh, ts, i, known[i], out);
        let (mut error, edges) =
            lattice_error(&values[range.clone()], &linear[range.clone()], &owner[range], known);
        if let Some(grid) = sampler.surface.grid() {
            let corners = mesh.triangle(ts[i] as usize).map(|v| mesh.vertex(v));
            error = worst_node(grid, corners.map(|v| in_grid(grid, v)), corners.map(|v| v.z), error).error;
        }
        out.push((error, edges));
        next += usize::from(count);
    }
    sampler.batch = batch;
    Ok(())
}

/// Vertex `v`'s position in grid units.
fn in_grid(grid: &crate::source::Grid, v: Vertex) -> Point {
    let (u, w) = grid.to_grid(v.point());
    Point::new(u, w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Rect;
    use crate::refine::{Params, refine};
    use crate::source::Expression;
    use proptest::prelude::*;

    proptest! {
        /// A batch of triangles, some edges known from outside and some shared within it,
        /// gets the bits and the evaluation count of estimating them one by one.
        #[test]
        fn a_batch_estimates_as_one_triangle_at_a_time_does(
            n in 20usize..300,
            picks in proptest::collection::vec(any::<u16>(), 1..12),
            outside in any::<u64>(),
        ) {
            let f = Expression::parse("sin(5*x)*cos(3*y) + x^2*y").unwrap();
            let mesh = refine(&f, Rect::unit(), &Params::new(n).unwrap(), &mut ()).unwrap().mesh;
            let mut ts: Vec<u32> = picks.iter().map(|&p| u32::from(p) % mesh.num_triangles() as u32).collect();
            ts.sort_unstable();
            ts.dedup();
            // Edges whose neighbour is outside the batch are known or not, by the bits of `outside`.
            let known: Vec<[Option<f64>; 3]> = ts.iter().enumerate().map(|(i, &t)| {
                std::array::from_fn(|k| {
                    let f = mesh.twin(3 * t + k as u32);
                    let inside = f != NONE && ts.contains(&(f / 3));
                    (!inside && outside >> ((3 * i + k) % 64) & 1 == 1).then_some(0.25 * (k + 1) as f64)
                })
            }).collect();
            let mut batched = Sampler { surface: &f, evaluations: 0, batch: Batch::default() };
            let mut out = Vec::new();
            triangles_error(&mesh, &ts, &known, &mut batched, &mut out).unwrap();
            let mut single = Sampler { surface: &f, evaluations: 0, batch: Batch::default() };
            let mut expected: Vec<(f64, [f64; 3])> = Vec::new();
            for (i, &t) in ts.iter().enumerate() {
                // As the refinement did before batches: a triangle estimated earlier in the
                // step is fresh, and its neighbour reads the shared edge from it.
                let known: [Option<f64>; 3] = std::array::from_fn(|k| {
                    let f = mesh.twin(3 * t + k as u32);
                    let earlier = (f != NONE).then(|| ts[..i].iter().position(|&u| u == f / 3)).flatten();
                    known[i][k].or(earlier.map(|j| expected[j].1[(f % 3) as usize]))
                });
                expected.push(triangle_error(&mesh, t, &mut single, known).unwrap());
            }
            let bits = |v: &[(f64, [f64; 3])]| v.iter().map(|(e, k)| (e.to_bits(), k.map(f64::to_bits))).collect::<Vec<_>>();
            prop_assert_eq!(bits(&out), bits(&expected));
            prop_assert_eq!(batched.evaluations, single.evaluations);
        }
    }

    /// Triangle 0 of S4 on [0,1]×[0,0.5] is P1 P2 P3: a bottom side of length 1, a right side
    /// of 0.5 and the diagonal P3→P1 of √1.25.
    fn slot(error: f64, edges: [f64; 3]) -> Slot {
        Slot { error, edges }
    }

    #[test]
    fn semi_recursive_bisects_the_worst_edge_among_the_long_ones() {
        let mesh = Mesh::new(Rect::new(0.0, 1.0, 0.0, 0.5).unwrap(), [0.0; 4]);
        let [p1, p2, p3] = mesh.triangle(0);
        let ends = |e: u32| (mesh.origin(e), mesh.dest(e));
        assert_eq!(ends(longest_edge(&mesh, 0)), (p3, p1));
        // The bottom side is 0.8 of the diagonal's squared length: eligible.
        assert_eq!(ends(split_edge(&mesh, 0, &slot(2.0, [2.0, 0.0, 1.0]))), (p1, p2));
        // The right side (0.2 of it) is too short however large its error.
        assert_eq!(ends(split_edge(&mesh, 0, &slot(3.0, [2.0, 3.0, 1.0]))), (p1, p2));
        assert_eq!(ends(split_edge(&mesh, 0, &slot(3.0, [0.0, 3.0, 1.0]))), (p3, p1));
        // The worst sample is inside: the longest edge, whatever the edges say.
        assert_eq!(ends(split_edge(&mesh, 0, &slot(5.0, [2.0, 0.0, 1.0]))), (p3, p1));
        // Ties keep the longest edge.
        assert_eq!(ends(split_edge(&mesh, 0, &slot(2.0, [2.0, 0.0, 2.0]))), (p3, p1));
    }
}
