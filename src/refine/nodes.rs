//! Criterion `error` on a grid with `semi-recursive` or `data-dependent`: every new vertex is a
//! grid node, the worst one of the worst triangle (greedy insertion: Garland and Heckbert 1995,
//! as in hmm); `data-dependent` then flips the worst triangles' edges where that lowers the
//! largest error ([`flip_worst`]).
//!
//! A grid's data are its nodes. An edge midpoint lies between them, where F is only the
//! bilinear interpolant, so once edges near the node spacing a midpoint vertex no longer sits
//! on the data and the error at the nodes stops falling. Here e(T) is the largest
//! |value − F_n| over the nodes in the closed triangle, found exactly (no lattice of samples),
//! and a step inserts the node where it is reached, with the node's own value: F_n is exact
//! there from then on. Lawson flips keep the mesh Delaunay.
//!
//! A triangle whose nodes F_n matches (often one with no node off its corners) has e(T) = 0
//! and leaves the queue; when all have, F_n matches every node and the run stops as
//! `exhausted`. An encroached side splits at its node nearest the midpoint, and a triangle
//! below `min_angle` at the midpoint of its longest-edge path's end (see [`super::angles`]).
//! `recursive` keeps midpoints: Rivara's bisection needs them for its bound on the angles.
//!
//! A terrain tile's grid is a lattice that resamples a DEM between the DEM's own samples; the
//! DEM is its data. With those `samples`, a triangle that holds some is measured at them and
//! its worst sample inserted itself (flagged [`SAMPLE`] in its slot), so the mesh is within
//! the tolerance of the DEM where the lattice alone could not be.

use super::angles::{self, Encroachment, Repair, Repairs, terminal_edge};
use super::observer::Observer;
use super::outcome::StopReason;
use super::params::Method;
use super::run::Run;
use super::worst_triangle::{Entry, WorstTriangleQueue};
use crate::geom::predicates::{is_ccw, signed_area_x2};
use crate::geom::{Mesh, NONE, Point, Vertex, raster};
use crate::source::{BLOCK, Grid, Surface};

/// No node: a triangle whose nodes F_n matches. (An `Option` would make a slot 24 bytes.)
const NO_NODE: (u32, u32) = (u32::MAX, u32::MAX);

/// Set in a slot's i: the node is a sample of the data the grid was resampled from
/// ([`Estimates::probe`]), not a grid node. Columns stay far below it (2^31 would be 16 GiB
/// a row).
const SAMPLE: u32 = 1 << 31;

/// How far inside the grid's sides, in node spacings, a sample must lie to be inserted: one
/// nearer would go onto the side, which a tile never splits. A caller passes only samples
/// clear of them (see `tiles`), so that none of those it leaves out hides another.
pub const SAMPLE_CLEARANCE: f64 = 0.01;

/// What is known of one triangle slot: e(T) and the node where it is reached.
#[derive(Debug, Clone, Copy)]
struct Slot {
    error: f64,
    /// Node (i, j), or [`NO_NODE`]. Kept as a pair, not `j·nx + i`: taking that apart again
    /// cost two 64-bit divisions per estimate.
    node: (u32, u32),
}

/// Triangle errors and the queue over those above zero.
struct Estimates<'g> {
    grid: &'g Grid,
    /// The data `grid` was resampled from, if any (a DEM under a terrain tile's lattice): the
    /// error is measured at its samples too.
    samples: Option<&'g Grid>,
    /// Each vertex's position in grid units: a node's exact (i, j), so that F_n there is its
    /// value up to the plane's rounding, which the corner rule below takes out.
    at: Vec<Point>,
    queue: WorstTriangleQueue,
    slots: Vec<Slot>,
    next_seq: u32,
}

impl Estimates<'_> {
    /// Measures triangle `t` and queues it when its error is above zero.
    fn estimate<O: Observer>(&mut self, mesh: &Mesh, t: u32, observer: &mut O) {
        let slot = self.measure(mesh, mesh.triangle(t as usize));
        observer.estimated(t, slot.error);
        self.set(t, slot);
    }

    /// e(T) and its node for the triangle with these corners (in the mesh or not).
    fn measure(&self, mesh: &Mesh, corners: [u32; 3]) -> Slot {
        let z = corners.map(|v| mesh.vertex(v).z);
        // With the data the grid resampled, a triangle over them is measured at them alone;
        // one that reaches beyond them (past the data's edge) at its grid nodes too.
        let over_samples = self.samples.and_then(|samples| {
            let slot = self.probe(mesh, samples, corners, z)?;
            Some((slot, corners.iter().all(|&v| within(samples, mesh.point(v)))))
        });
        match over_samples {
            Some((slot, true)) => slot,
            Some((slot, false)) => {
                let nodes = self.at_nodes(corners, z);
                if nodes.error > slot.error { nodes } else { slot }
            }
            None => self.at_nodes(corners, z),
        }
    }

    /// e(T) over the grid's nodes in the triangle, and the node where it is reached.
    ///
    /// When the worst node is a corner, every node's deviation is within the plane's rounding
    /// (a few units in the last place of z at the other corners): F_n matches the triangle's
    /// nodes, and its error is 0.
    fn at_nodes(&self, corners: [u32; 3], z: [f64; 3]) -> Slot {
        let in_grid = corners.map(|v| self.at[v as usize]);
        let worst = worst_node(self.grid, in_grid, z, 0.0);
        let node = worst.node(self.grid);
        let is_corner =
            |(i, j): (u32, u32)| in_grid.iter().any(|p| p.x == f64::from(i) && p.y == f64::from(j));
        match node.filter(|&node| !is_corner(node)) {
            None => Slot { error: 0.0, node: NO_NODE },
            Some(node) => Slot { error: worst.error, node },
        }
    }

    /// For a triangle that holds samples of the data the grid was resampled from, e(T) is
    /// their largest |value − F_n|, reached by inserting the worst sample itself with its own
    /// value (a grid that resamples the data between its samples cannot match them at its
    /// nodes); `None` for a triangle that holds none, which the grid's nodes measure. A
    /// sample within [`SAMPLE_CLEARANCE`] of the grid's sides is never inserted (a tile never
    /// splits a side): the caller passes only samples clear of them.
    fn probe(&self, mesh: &Mesh, samples: &Grid, corners: [u32; 3], z: [f64; 3]) -> Option<Slot> {
        let in_samples = corners.map(|v| {
            let (u, w) = samples.to_grid(mesh.point(v));
            Point::new(u, w)
        });
        // Below any deviation: the run is found whenever the triangle holds a sample.
        let worst = worst_node(samples, in_samples, z, -1.0);
        let (si, sj) = worst.node(samples)?;
        let (u, w) = self.grid.to_grid(samples.node(si as usize, sj as usize));
        let clear = |k: f64, n: usize| k >= SAMPLE_CLEARANCE && k <= (n - 1) as f64 - SAMPLE_CLEARANCE;
        Some(if worst.error > 0.0 && si < SAMPLE && clear(u, self.grid.nx()) && clear(w, self.grid.ny()) {
            Slot { error: worst.error, node: (si | SAMPLE, sj) }
        } else {
            Slot { error: 0.0, node: NO_NODE }
        })
    }

    /// Gives triangle `t` what [`Estimates::measure`] found, in its slot and the queue.
    fn set(&mut self, t: u32, slot: Slot) {
        if self.slots.len() <= t as usize {
            self.slots.resize(t as usize + 1, Slot { error: 0.0, node: NO_NODE });
        }
        self.slots[t as usize] = slot;
        if slot.node == NO_NODE {
            self.queue.remove(t);
        } else {
            self.queue.set(Entry { error: slot.error, seq: self.next_seq, t });
            self.next_seq += 1;
        }
    }
}

/// Refines `mesh`, whose vertices are all grid nodes (S₄, or S₄ with nodes on its sides), by
/// inserting the worst node of the worst triangle until a stop rule fires. With
/// `fixed_sides`, a node on the rectangle's sides is never inserted: a triangle whose worst
/// node is there is retired. With `samples` (the data `grid` was resampled from), a triangle
/// that holds some is measured at them instead, and the worst inserted itself
/// ([`Estimates::probe`]). Returns why it stopped and every triangle's e(T), by index.
/// `evaluations` counts the node values taken as vertices (a node is read, not evaluated,
/// but it is F's value there).
pub(super) fn refine<O: Observer>(
    mesh: &mut Mesh,
    grid: &Grid,
    run: &mut Run<'_, O>,
    evaluations: &mut u64,
    fixed_sides: bool,
    samples: Option<&Grid>,
) -> (StopReason, Vec<f64>) {
    run.observer.on_nodes();
    // Sized for the budget (capped for huge ones), so the run does not copy them as they grow.
    let room = run.params.max_vertices().min(1 << 24);
    // Each vertex is a node: its exact (i, j), where to_grid would round it.
    let mut at = Vec::with_capacity(room);
    at.extend(mesh.vertices().iter().map(|v| {
        let (i, j) = grid.to_grid(Point::new(v.x, v.y));
        debug_assert!((i - i.round()).abs() < 1e-6 && (j - j.round()).abs() < 1e-6, "a vertex off the nodes");
        Point::new(i.round(), j.round())
    }));
    let (last_i, last_j) = (grid.nx() - 1, grid.ny() - 1);
    let on_side = |(i, j): (usize, usize)| i == 0 || j == 0 || i == last_i || j == last_j;
    let mut estimates = Estimates {
        grid,
        samples,
        at,
        queue: WorstTriangleQueue::with_capacity(2 * room),
        slots: Vec::with_capacity(2 * room),
        next_seq: 0,
    };
    for t in 0..mesh.num_triangles() as u32 {
        estimates.estimate(mesh, t, run.observer);
    }
    run.observer.started(*evaluations);
    // Fixed sides are never split, so nothing may ask for it.
    let encroachment = if fixed_sides { Encroachment::Never } else { Encroachment::Circle };
    let mut repairs = Repairs::new(encroachment, run.params.min_angle());
    // Triangles a step rewrote, measured again after it; reused so steps do not allocate.
    let mut touched: Vec<u32> = Vec::with_capacity(32);
    let stop = loop {
        let repair = match run.begin_step(mesh, estimates.queue.peek().map(|e| e.error), &mut repairs) {
            Ok(repair) => repair,
            Err(stop) => break stop,
        };
        let (e, (vertex, in_grid)) = match repair {
            Some((_, Repair::Encroached(h))) => (h, side_split(grid, mesh, h)),
            Some((t, Repair::Skinny)) => {
                // An angle is a matter of geometry, not data: the midpoint, F bilinear there.
                let e = terminal_edge(mesh, t);
                (e, midpoint(grid, mesh, e))
            }
            None => {
                let worst = estimates.queue.pop().expect("the queue's top");
                let (i, j) = estimates.slots[worst.t as usize].node;
                debug_assert_ne!((i, j), NO_NODE, "a queued triangle has a node");
                if let Some(samples) = samples
                    && i & SAMPLE != 0
                {
                    let (vertex, in_grid) = on_sample(grid, samples, (i & !SAMPLE) as usize, j as usize);
                    (nearest_edge(mesh, worst.t, vertex.point()), (vertex, in_grid))
                } else {
                    let (i, j) = (i as usize, j as usize);
                    if fixed_sides && on_side((i, j)) {
                        // Within rounding of the tolerance there, which its side was simplified to.
                        run.retire();
                        run.observer.retired(mesh.origin(3 * worst.t), mesh.dest(3 * worst.t));
                        run.observer.stepped(None, *evaluations);
                        continue;
                    }
                    let p = grid.node(i, j);
                    (nearest_edge(mesh, worst.t, p), on_node(grid, i, j))
                }
            }
        };
        run.observer.selected(mesh, mesh.origin(e), mesh.dest(e));
        touched.clear();
        let split = run.insert_vertex(mesh, e, vertex, |mesh, d| touched.extend([d / 3, mesh.twin(d) / 3]));
        let Some(split) = split else {
            // Too close to an edge or a corner to insert: the triangle stays, out of the queue
            // (or, for a repair, unrepaired).
            run.observer.retired(mesh.origin(e), mesh.dest(e));
            run.observer.stepped(None, *evaluations);
            continue;
        };
        *evaluations += 1;
        estimates.at.push(in_grid);
        touched.extend(split.link().iter().map(|&h| h / 3));
        touched.sort_unstable();
        touched.dedup();
        for &t in &touched {
            estimates.estimate(mesh, t, run.observer);
        }
        repairs.look_at(&touched);
        run.observer.inserted(mesh, split.vertex);
        run.observer.stepped(Some(e), *evaluations);
    };
    if run.params.method() == Method::DataDependent && stop != StopReason::Cancelled {
        run.flips += flip_worst(mesh, &mut estimates, run);
    }
    let errors = estimates.slots[..mesh.num_triangles()].iter().map(|s| s.error).collect();
    (stop, errors)
}

/// Method `data-dependent`, once refinement has stopped: while flipping an edge of the worst
/// triangle lowers the larger error of the two triangles beside it below the worst, makes the
/// flip that lowers it most (the first edge among equals). Returns the number of flips kept.
///
/// Greedy insertion often leaves its last worst triangles isolated above the rest (on the DEMs
/// of docs/terrain.md at 10^4 vertices, one or two triangles 10–35% above the next), and a flip
/// often brings such a triangle's worst node into a better-fitting pair: the data-dependent
/// triangulation of Dyn, Levin and Rippa (1990), aimed at the maximum. Each flip replaces a
/// triangle at the largest error and its neighbour by two below it, so the errors sorted from
/// the top fall lexicographically and the loop ends, at the first worst triangle that no flip
/// helps. The flips made since the largest error last fell lowered no maximum (where many
/// triangles share it, as on heights quantised to a tile's steps, one of them is stuck): they
/// are undone, so that the mesh leaves the Delaunay one only where that buys a lower maximum.
fn flip_worst<O: Observer>(mesh: &mut Mesh, estimates: &mut Estimates<'_>, run: &mut Run<'_, O>) -> u64 {
    let skinny = run.params.min_angle().map(angles::cos_sq_of);
    let Some(mut level) = estimates.queue.peek().map(|e| e.error) else { return 0 };
    // The new diagonals of the flips made since the largest error last fell, by their ends:
    // undoing a later flip rewrites slots, so only the ends name a diagonal for sure.
    let mut pending: Vec<(u32, u32)> = Vec::new();
    let mut kept = 0;
    loop {
        let Some(worst) = estimates.queue.peek() else {
            // Every node is matched: no maximum is left to lower.
            kept += pending.len() as u64;
            return kept;
        };
        if worst.error < level {
            // No triangle is left at the old maximum: the flips that took them stay.
            kept += pending.len() as u64;
            pending.clear();
            level = worst.error;
        }
        if run.observer.is_cancelled() {
            break;
        }
        let Some((h, [s0, s1])) = best_flip(mesh, estimates, worst, run.floors, skinny) else { break };
        let [a, b] = mesh.flip(h);
        estimates.set(a / 3, s0);
        estimates.set(b / 3, s1);
        // The new diagonal runs from a's end to its apex (w → m).
        pending.push((mesh.dest(a), mesh.apex(a)));
    }
    for &(w, m) in pending.iter().rev() {
        let diagonal = mesh.find_edge(w, m).expect("undoing the flips after it brought the diagonal back");
        let [a, b] = mesh.flip(diagonal);
        for t in [a / 3, b / 3] {
            estimates.set(t, estimates.measure(mesh, mesh.triangle(t as usize)));
        }
    }
    kept
}

/// The flip of an edge of the `worst` triangle that lowers the larger error of its two new
/// triangles the most below the worst's, with their estimates; `None` when none does. A flip
/// must leave strictly convex triangles (exact orientation) above the area floor, and none
/// below `min_angle` (`skinny`, its cos²) when one is set.
fn best_flip(
    mesh: &Mesh,
    estimates: &Estimates<'_>,
    worst: Entry,
    floors: super::Floors,
    skinny: Option<f64>,
) -> Option<(u32, [Slot; 2])> {
    let mut best: Option<(f64, u32, [Slot; 2])> = None;
    for h in 3 * worst.t..3 * worst.t + 3 {
        let f = mesh.twin(h);
        if f == NONE || mesh.is_constrained(h) {
            continue;
        }
        let new = mesh.flipped(h);
        let fits = |&[a, b, c]: &[u32; 3]| {
            let (a, b, c) = (mesh.point(a), mesh.point(b), mesh.point(c));
            is_ccw(a, b, c)
                && signed_area_x2(a, b, c) > floors.at(a, b).1
                && skinny.is_none_or(|cos_sq| angles::smallest_angle_cos_sq(a, b, c) <= cos_sq)
        };
        if !new.iter().all(fits) {
            continue;
        }
        let slots = new.map(|corners| estimates.measure(mesh, corners));
        let error = slots[0].error.max(slots[1].error);
        if error < best.map_or(worst.error, |(e, _, _)| e) {
            best = Some((error, h, slots));
        }
    }
    best.map(|(_, h, slots)| (h, slots))
}

/// Where the encroached boundary edge of half-edge `h` splits: at the side's node nearest its
/// midpoint, on the data, when one lies between its ends (half a node spacing clear of
/// both); otherwise at the midpoint, F bilinear there.
fn side_split(grid: &Grid, mesh: &Mesh, h: u32) -> (Vertex, Point) {
    let (a, b) = (mesh.point(mesh.origin(h)), mesh.point(mesh.dest(h)));
    let ((ua, va), (ub, vb)) = (grid.to_grid(a), grid.to_grid(b));
    let (um, vm) = grid.to_grid(a.midpoint(b));
    let (i, j) = (um.round(), vm.round());
    let between = |k: f64, p: f64, q: f64| k >= p.min(q) + 0.5 && k <= p.max(q) - 0.5;
    match if a.y == b.y { between(i, ua, ub) } else { between(j, va, vb) } {
        // Both are within the grid, as the midpoint of a side is.
        true => on_node(grid, i as usize, j as usize),
        false => midpoint(grid, mesh, h),
    }
}

/// Node (i, j) as a vertex with its value, and its position in grid units.
fn on_node(grid: &Grid, i: usize, j: usize) -> (Vertex, Point) {
    let p = grid.node(i, j);
    (Vertex { x: p.x, y: p.y, z: grid.value(i, j) }, Point::new(i as f64, j as f64))
}

/// Whether `p` lies within one and a half sample spacings of `samples`' rectangle: on the
/// data, or between its outer samples and a side of the grid it was clipped to, not beyond
/// the data's edge.
fn within(samples: &Grid, p: Point) -> bool {
    let r = samples.rect();
    let dx = 1.5 * (r.x1() - r.x0()) / (samples.nx() - 1) as f64;
    let dy = 1.5 * (r.y1() - r.y0()) / (samples.ny() - 1) as f64;
    (r.x0() - dx..=r.x1() + dx).contains(&p.x) && (r.y0() - dy..=r.y1() + dy).contains(&p.y)
}

/// Sample (i, j) of `samples` as a vertex with its value, and its position in `grid`'s units.
fn on_sample(grid: &Grid, samples: &Grid, i: usize, j: usize) -> (Vertex, Point) {
    let p = samples.node(i, j);
    let (u, w) = grid.to_grid(p);
    (Vertex { x: p.x, y: p.y, z: samples.value(i, j) }, Point::new(u, w))
}

/// The midpoint of half-edge `e` as a vertex, F bilinear there, and its position in grid units.
fn midpoint(grid: &Grid, mesh: &Mesh, e: u32) -> (Vertex, Point) {
    let m = mesh.point(mesh.origin(e)).midpoint(mesh.point(mesh.dest(e)));
    let (u, w) = grid.to_grid(m);
    (Vertex { x: m.x, y: m.y, z: grid.eval(m) }, Point::new(u, w))
}

/// The half-edge of triangle `t` nearest `p`, by the twice-area of the triangle it makes with
/// `p` (negative beyond the edge); among equal ones, the first. `p` goes inside `t` when it
/// clears every edge by the area floor, and otherwise on this edge.
pub(super) fn nearest_edge(mesh: &Mesh, t: u32, p: Point) -> u32 {
    let area = |e: u32| signed_area_x2(mesh.point(mesh.origin(e)), mesh.point(mesh.dest(e)), p);
    (3 * t + 1..3 * t + 3).fold(3 * t, |best, e| if area(e) < area(best) { e } else { best })
}

/// The largest |value − F_n| over a triangle's grid nodes and the run of a row that holds it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Worst {
    /// The largest error found, or the floor it had to beat.
    pub error: f64,
    /// Where it was found: row j, the run's first and last node, and the plane along the row
    /// with the run's first node `k0` steps along it.
    run: Option<(usize, usize, usize, i32, raster::PlaneRow)>,
}

impl Worst {
    /// Node (i, j), the first of the run that reaches [`Worst::error`], or `None` when no node
    /// beat the floor. A second look at one run of at most a row's span.
    fn node(&self, grid: &Grid) -> Option<(u32, u32)> {
        let (j, first, last, k0, line) = self.run?;
        // The same steps as the scan's, so the same bits.
        let i = (first..=last)
            .zip(k0..)
            .find(|&(i, k)| (grid.row(j)[i] - line.at(k)).abs() == self.error)
            .map(|(i, _)| i)
            .expect("the run holds its maximum");
        // Both fit, below NO_NODE's u32::MAX: a row or column of 2^32 nodes would hold 64 GiB.
        let narrow =
            |k: usize| u32::try_from(k).ok().filter(|&k| k < u32::MAX).expect("a grid index below 2^32 − 1");
        Some((narrow(i), narrow(j)))
    }
}

/// The larger of `floor` and max |value − F_n| over the grid nodes in the closed triangle with
/// corners `in_grid` (in grid units) and values `z`, with the run of nodes that first reaches
/// it in row order.
///
/// A run of nodes within one of the grid's blocks is passed over when its bound cannot beat
/// the largest error so far: its values lie in the block's range, and the plane's along the
/// run between its ends (stepped values are monotone), so |value − F_n| is at most
/// max(block max − plane min, plane max − block min), and the rounded differences obey the
/// same bound (rounding is monotone). The result is the same maximum, to the bit, as a scan
/// of every node; the order of the scan does not change a maximum.
pub(super) fn worst_node(grid: &Grid, in_grid: [Point; 3], z: [f64; 3], floor: f64) -> Worst {
    // Made at the first span: a triangle smaller than a grid cell often holds no node.
    let mut plane = None;
    let mut worst = Worst { error: floor, run: None };
    raster::for_each_span(in_grid, grid.nx(), grid.ny(), |j, i0, i1| {
        let plane = plane.get_or_insert_with(|| raster::Plane::new(in_grid, z));
        // A triangle flat in floating point covers no area: its nodes are its neighbours'.
        let Some(plane) = plane else { return };
        let (values, row) = (grid.row(j), plane.row_at(i0, j));
        let scan = |worst: &mut Worst, first: usize, last: usize| {
            // Steps from i0 fit an i32: a row has at most a few hundred million nodes.
            let k0 = (first - i0) as i32;
            let error = row.max_deviation(k0, &values[first..=last], worst.error);
            if error > worst.error {
                *worst = Worst { error, run: Some((j, first, last, k0, row)) };
            }
        };
        if i1 - i0 < 2 * BLOCK {
            // Too short a span for a bound to pay for itself: scan it.
            scan(&mut worst, i0, i1);
            return;
        }
        let mut first = i0;
        while first <= i1 {
            let block = first / BLOCK;
            let last = ((block + 1) * BLOCK - 1).min(i1);
            let (a, b) = (row.at((first - i0) as i32), row.at((last - i0) as i32));
            let (lo, hi) = grid.block_range(j, block);
            if (hi - a.min(b)).max(a.max(b) - lo) > worst.error {
                scan(&mut worst, first, last);
            }
            first = last + 1;
        }
    });
    worst
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Rect;
    use crate::refine::ParamsBuilder;
    use crate::refine::{Method, Params, refine};
    use proptest::prelude::*;

    /// The oracle: every node of the triangle compared, none passed over.
    fn every_node(grid: &Grid, corners: [Vertex; 3], floor: f64) -> (f64, Option<(u32, u32)>) {
        let in_grid = corners.map(|v| {
            let (u, w) = grid.to_grid(v.point());
            Point::new(u, w)
        });
        let Some(plane) = raster::Plane::new(in_grid, corners.map(|v| v.z)) else { return (floor, None) };
        let (mut error, mut node) = (floor, None);
        raster::for_each_span(in_grid, grid.nx(), grid.ny(), |j, i0, i1| {
            for (i, linear) in (i0..=i1).zip(plane.row(i0, j)) {
                let e = (grid.value(i, j) - linear).abs();
                if e > error {
                    (error, node) = (e, Some((i as u32, j as u32)));
                }
            }
        });
        (error, node)
    }

    /// |value − F_n| at node (i, j) of the triangle, as the oracle computes it.
    fn every_node_error_at(grid: &Grid, corners: [Vertex; 3], i: usize, j: usize) -> f64 {
        let in_grid = corners.map(|v| {
            let (u, w) = grid.to_grid(v.point());
            Point::new(u, w)
        });
        let plane = raster::Plane::new(in_grid, corners.map(|v| v.z)).unwrap();
        let mut found = None;
        raster::for_each_span(in_grid, grid.nx(), grid.ny(), |row, i0, i1| {
            if row == j && (i0..=i1).contains(&i) {
                let linear = plane.row(i0, j).nth(i - i0).unwrap();
                found = Some((grid.value(i, j) - linear).abs());
            }
        });
        found.expect("the node is in the triangle")
    }

    /// A smooth surface with a few spikes, so that some blocks hold the maximum.
    fn spiky(nx: usize, ny: usize, seed: u64) -> Grid {
        let values = (0..nx * ny)
            .map(|k| {
                let (i, j) = ((k % nx) as f64, (k / nx) as f64);
                let spike = (k as u64).wrapping_mul(2654435761).wrapping_add(seed).is_multiple_of(997);
                (i * 0.05).sin() + (j * 0.03).cos() + if spike { 4.0 } else { 0.0 }
            })
            .collect();
        Grid::new(nx, ny, values).unwrap()
    }

    proptest! {
        #[test]
        fn passing_over_blocks_finds_the_same_maximum_and_node_as_every_node(
            seed in 0u64..1000,
            corners in proptest::array::uniform3((0.0f64..300.0, 0.0f64..200.0, -5.0f64..5.0)),
            floor in prop_oneof![Just(0.0), 0.0f64..3.0],
        ) {
            let grid = spiky(301, 201, seed);
            let corners = corners.map(|(x, y, z)| Vertex { x, y, z });
            let in_grid = corners.map(|v| {
                let (u, w) = grid.to_grid(v.point());
                Point::new(u, w)
            });
            let worst = worst_node(&grid, in_grid, corners.map(|v| v.z), floor);
            let (error, node) = every_node(&grid, corners, floor);
            prop_assert_eq!(worst.error.to_bits(), error.to_bits());
            // A node that reaches the maximum, and the first one in row order.
            let found = worst.node(&grid);
            prop_assert_eq!(found, node);
            if let Some((i, j)) = found {
                let (i, j) = (i as usize, j as usize);
                let at = every_node_error_at(&grid, corners, i, j);
                prop_assert_eq!(at.to_bits(), error.to_bits(), "node ({}, {})", i, j);
            }
        }
    }

    /// A grid with one sharp peak and a ridge, off the dyadic lines of the domain.
    fn terrain() -> Grid {
        let (nx, ny) = (61, 45);
        let values = (0..nx * ny)
            .map(|k| {
                let (x, y) = ((k % nx) as f64, (k / nx) as f64);
                100.0 * (-((x - 17.0).powi(2) + (y - 29.0).powi(2)) / 8.0).exp() + 0.3 * (x - 2.0 * y).abs()
            })
            .collect();
        Grid::new(nx, ny, values).unwrap()
    }

    #[test]
    fn every_vertex_is_a_grid_node_with_its_value_and_the_mesh_stays_delaunay() {
        let grid = terrain().with_domain(Rect::new(-3.0, 9.0, 1.0, 5.4).unwrap());
        let run = refine(&grid, grid.rect(), &Params::new(400).unwrap(), &mut ()).unwrap();
        run.mesh.check_invariants().unwrap();
        assert!(run.stats.delaunay && run.mesh.is_delaunay());
        assert_eq!(run.mesh.num_vertices(), 400);
        let on_node = |v: &Vertex| {
            let (u, w) = grid.to_grid(v.point());
            let (i, j) = (u.round() as usize, w.round() as usize);
            grid.node(i, j) == v.point() && grid.value(i, j) == v.z
        };
        assert!(run.mesh.vertices().iter().all(on_node), "a vertex off the nodes");
        // The errors the run kept are the nodes' errors, up to the rounding of planes made in
        // grid units rather than from the vertices' coordinates.
        let exact = crate::refine::estimate_error(&run.mesh, &grid).max_error;
        let kept = run.stats.max_triangle_error.unwrap();
        assert!((kept - exact).abs() <= 1e-9 * exact, "{kept} vs {exact}");
    }

    #[test]
    fn a_grid_that_a_mesh_matches_stops_once_every_node_is_matched() {
        // A plane on two rows but for one node.
        let mut values: Vec<f64> = (0..14).map(|k| f64::from(k % 7) * 0.5).collect();
        values[4] = 9.0;
        let grid = Grid::new(7, 2, values).unwrap();
        let run = refine(&grid, grid.rect(), &Params::new(50).unwrap(), &mut ()).unwrap();
        assert_eq!(run.stats.stop, StopReason::Exhausted);
        assert_eq!(run.stats.max_triangle_error, Some(0.0));
        // The peak (4, 0), then (3, 0) and (5, 0) bring the bottom row onto its values; the
        // rest split the sides those vertices encroach, at nodes.
        let added: Vec<(usize, usize)> = run.mesh.vertices()[4..]
            .iter()
            .map(|v| {
                let (i, j) = (v.x as usize, v.y as usize);
                assert_eq!((grid.node(i, j), grid.value(i, j)), (v.point(), v.z), "a vertex off the nodes");
                (i, j)
            })
            .collect();
        assert_eq!(added[0], (4, 0));
        assert!([(3, 0), (5, 0)].iter().all(|n| added.contains(n)), "{added:?}");
        assert!(added.len() < 14 - 4, "every node taken: {added:?}");
    }

    #[test]
    fn nodes_reach_a_lower_error_at_the_nodes_than_midpoints_at_equal_vertices() {
        // Recursive bisects midpoints on the same grid: the nodes' errors fall faster here.
        let grid = terrain();
        let params = Params::new(300).unwrap();
        let on_nodes = refine(&grid, grid.rect(), &params, &mut ()).unwrap();
        let midpoints = refine(
            &grid,
            grid.rect(),
            &Params::builder(300).method(Method::Recursive).build().unwrap(),
            &mut (),
        )
        .unwrap();
        let error = |r: &crate::refine::Refinement| crate::refine::estimate_error(&r.mesh, &grid).max_error;
        assert!(error(&on_nodes) < 0.5 * error(&midpoints), "{} vs {}", error(&on_nodes), error(&midpoints));
    }

    /// The mesh's edges as sorted pairs of vertex ids.
    fn edges(mesh: &Mesh) -> std::collections::BTreeSet<(u32, u32)> {
        mesh.edges().map(|e| (e.a.min(e.b), e.a.max(e.b))).collect()
    }

    /// The same request with `semi-recursive` and with `data-dependent`.
    fn both(grid: &Grid, params: &ParamsBuilder) -> (crate::refine::Refinement, crate::refine::Refinement) {
        let run = |method| {
            let params = params.clone().method(method).on_grid(true).build().unwrap();
            refine(grid, grid.rect(), &params, &mut ()).unwrap()
        };
        (run(Method::SemiRecursive), run(Method::DataDependent))
    }

    #[test]
    fn data_dependent_flips_lower_an_isolated_worst_triangle_on_the_same_vertices() {
        let grid = terrain();
        let (delaunay, flipped) = both(&grid, &Params::builder(200));
        assert_eq!(flipped.mesh.vertices(), delaunay.mesh.vertices());
        flipped.mesh.check_invariants().unwrap();
        let (before, after) =
            (delaunay.stats.max_triangle_error.unwrap(), flipped.stats.max_triangle_error.unwrap());
        // The greedy run's last worst triangle stands well above the rest (0.062 and 0.030).
        assert!(after < 0.6 * before, "{after} vs {before}");
        assert!(flipped.stats.flips > delaunay.stats.flips);
        assert!(delaunay.stats.delaunay && !flipped.stats.delaunay && !flipped.mesh.is_delaunay());
        // The errors kept through the flips are the nodes' errors of the final mesh.
        let exact = crate::refine::estimate_error(&flipped.mesh, &grid).max_error;
        assert!((after - exact).abs() <= 1e-9 * exact, "{after} vs {exact}");
    }

    #[test]
    fn a_flip_that_lowers_no_maximum_is_undone() {
        // At 190 vertices one flip helps a worst triangle, and another at the same error is
        // stuck: the maximum stays, and so does the Delaunay mesh.
        let grid = terrain();
        let (delaunay, flipped) = both(&grid, &Params::builder(190));
        assert_eq!(flipped.stats.max_triangle_error, delaunay.stats.max_triangle_error);
        assert_eq!(flipped.stats.flips, delaunay.stats.flips);
        assert!(flipped.stats.delaunay && flipped.mesh.is_delaunay());
        assert_eq!(edges(&flipped.mesh), edges(&delaunay.mesh));
        flipped.mesh.check_invariants().unwrap();
        let exact = crate::refine::estimate_error(&flipped.mesh, &grid).max_error;
        let kept = flipped.stats.max_triangle_error.unwrap();
        assert!((kept - exact).abs() <= 1e-9 * exact, "{kept} vs {exact}");
    }

    #[test]
    fn data_dependent_flips_make_no_triangle_below_min_angle() {
        let grid = terrain();
        let (delaunay, flipped) = both(&grid, &Params::builder(200).min_angle(20.0));
        let below = |r: &crate::refine::Refinement| r.stats.below_min_angle.unwrap();
        assert!(below(&flipped) <= below(&delaunay), "{} vs {}", below(&flipped), below(&delaunay));
        assert!(flipped.stats.max_triangle_error <= delaunay.stats.max_triangle_error);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Flips only: the vertices stay, the largest error never rises, every kept e(T) is
        /// the final triangle's, and where the maximum did not fall the mesh is the Delaunay
        /// one.
        #[test]
        fn data_dependent_never_raises_the_largest_error(seed in 0u64..1000, n in 20usize..400) {
            let grid = spiky(61, 45, seed);
            let (delaunay, flipped) = both(&grid, &Params::builder(n));
            prop_assert_eq!(flipped.mesh.vertices(), delaunay.mesh.vertices());
            flipped.mesh.check_invariants().unwrap();
            let (before, after) =
                (delaunay.stats.max_triangle_error.unwrap(), flipped.stats.max_triangle_error.unwrap());
            prop_assert!(after <= before, "{} > {}", after, before);
            let exact = crate::refine::estimate_error(&flipped.mesh, &grid).max_error;
            prop_assert!((after - exact).abs() <= 1e-9 * exact, "{} vs {}", after, exact);
            // Flips stay only where they lowered the maximum: otherwise the Delaunay mesh.
            if after == before {
                prop_assert_eq!(flipped.stats.flips, delaunay.stats.flips);
                prop_assert!(flipped.stats.delaunay);
                prop_assert_eq!(edges(&flipped.mesh), edges(&delaunay.mesh));
            } else {
                prop_assert!(flipped.stats.flips > delaunay.stats.flips);
            }
        }
    }
}
