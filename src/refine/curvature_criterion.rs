//! Criterion `curvature`: split the edge whose midpoint the vertices' gradients say is worst
//! interpolated, from F at the vertices alone (one evaluation a vertex, as `variation`).
//!
//! Each vertex carries a gradient g, that of the quadratic fitted in least squares to the
//! values around it ([`Gradients`]). Along an edge d = q − p the cubic that matches z and g·d
//! at both ends leaves the chord at the midpoint by (g_p − g_q)·d / 8: that is the edge's
//! value ([`value`]), |F − F_n| at the midpoint of a quadratic F. Where `variation` spreads
//! |zᵢ − zⱼ| (the slope) evenly, this spreads the interpolation error, so flat and straight
//! slopes get few vertices and bends many. An exploration term on the edge's length keeps
//! looking where the vertices lie on one plane, and encroached boundary edges, edges above
//! `max_size` and overflows go first.
//!
//! A split changes the triangles around the new vertex only, so the gradients of it and its
//! neighbours (and of the vertices that fit over two rings next to them) are fitted again and
//! their edges queued with new values; an entry whose value is no longer its edge's surfaces
//! later and is skipped. The queue is then a function of the mesh alone, which is what lets a
//! client job's replay resume from any of its meshes (`asked`). An edge shorter than twice
//! `min_size` is never queued, so no midpoint comes nearer than `min_size` to its edge's ends.

use super::angles::lens_encroached;
use super::estimator::Field;
use super::observer::Observer;
use super::outcome::StopReason;
use super::params::{Method, Params};
use super::run::Run;
use super::worst_edge::{Candidate, WorstEdgeQueue};
use crate::geom::Mesh;

/// Refines `mesh` worst edge first until a stop rule fires.
pub(super) fn refine<F: Field, O: Observer>(
    mesh: &mut Mesh,
    field: &mut F,
    run: &mut Run<'_, O>,
) -> Result<StopReason, F::Error> {
    let mut scales = Scales::of(run.params);
    let mut range = Range::of(mesh);
    scales.explore = range.explore(mesh);
    let mut grads = Gradients::new(mesh, run.params.max_vertices());
    let mut queue = Queue { heap: WorstEdgeQueue::new(), len: 0, scales };
    queue.refill(mesh, &grads.at);
    // The vertices whose gradients a step changed, reused so steps do not allocate.
    let mut touched: Vec<u32> = Vec::with_capacity(64);
    run.observer.started(field.evaluations());
    loop {
        let top = queue.settle(mesh, &grads.at);
        if let Err(stop) = run.begin_edge_step(mesh, top.map(|(c, _)| c.value)) {
            return Ok(stop);
        }
        let (worst, e) = top.expect("a step goes on with a queued edge");
        queue.pop(mesh);
        let (a, b) = (worst.a, worst.b);
        run.observer.selected(mesh, a, b);
        // A flip away from the new vertex (only after a midpoint rounded off its edge) changes
        // the fans of its quadrilateral's corners, which need not be the new vertex's
        // neighbours.
        let predicted = predicted(mesh, &grads.at, e);
        let split = run.split_midpoint(mesh, field, e, Some(predicted), |mesh, d| {
            touched.extend([mesh.origin(d), mesh.dest(d), mesh.apex(d)]);
            touched.push(mesh.apex(mesh.twin(d)));
        })?;
        let Some(split) = split else {
            touched.clear();
            run.observer.retired(a, b);
            run.observer.stepped(None, field.evaluations());
            continue;
        };
        grads.at.push([0.0; 2]);
        touched.push(split.vertex);
        mesh.for_each_neighbour(split.vertex, |other, _| touched.push(other));
        // A vertex that fits over two rings sees a change at its neighbours' fans too.
        for i in 0..touched.len() {
            mesh.for_each_neighbour(touched[i], |other, _| {
                if fits_wide(mesh, other) {
                    touched.push(other);
                }
            });
        }
        touched.sort_unstable();
        touched.dedup();
        for &v in &touched {
            grads.at[v as usize] = grads.fit(mesh, v);
        }
        // Each edge once: one between two touched vertices is queued from its smaller end.
        for &v in &touched {
            mesh.for_each_neighbour(v, |other, h| {
                if other > v || touched.binary_search(&other).is_err() {
                    queue.push(mesh, &grads.at, v, other, h);
                }
            });
        }
        touched.clear();
        if range.widened(mesh.vertex(split.vertex).z) {
            queue.scales.explore = range.explore(mesh);
            queue.refill(mesh, &grads.at);
        } else {
            queue.compact(mesh, &grads.at);
        }
        run.observer.inserted(mesh, split.vertex);
        run.observer.stepped(Some(e), field.evaluations());
    }
}

/// The exploration term's weight: an edge of length l gains EXPLORE · R · (l / D)², R the
/// range of the values seen, D the rectangle's diagonal (Learner2D's loss adds 0.3 of a
/// triangle's area, in the same normalised units). Without it a region whose vertices lie
/// on one plane is never looked at again, and a feature no vertex has touched stays unseen
/// (a ring between the first vertices); with it, such regions are refined uniformly, more
/// coarsely than the rest. Chosen by hand: bench/asktell.py at 0.1 and at 0.5 gave E_max in
/// one band (within ±40% on the bump, sin·cos and the ring), and both miss part of the ring
/// at 10³ points; tuning it is open.
const EXPLORE: f64 = 0.5;

/// The range of the values seen, and the coarser one the exploration term uses.
struct Range {
    lo: f64,
    hi: f64,
    /// The range rounded down to 6 bits of mantissa (steps of at most 1/64): a function of the
    /// mesh alone, so a run resumed from any of its meshes values edges as the run did.
    used: f64,
}

impl Range {
    fn of(mesh: &Mesh) -> Self {
        let z = mesh.vertices().iter().map(|v| v.z);
        let (lo, hi) = z.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), z| (lo.min(z), hi.max(z)));
        Self { lo, hi, used: coarse(hi - lo) }
    }

    /// Takes in a new value; true when the coarse range grew, so that the queue is valued
    /// again (a few dozen times a run, rarely once F's extremes are found).
    fn widened(&mut self, z: f64) -> bool {
        (self.lo, self.hi) = (self.lo.min(z), self.hi.max(z));
        let used = coarse(self.hi - self.lo);
        let grew = used != self.used;
        self.used = used;
        grew
    }

    /// The weight on an edge's squared length.
    fn explore(&self, mesh: &Mesh) -> f64 {
        let r = mesh.rect();
        let diagonal_sq = (r.x1() - r.x0()).powi(2) + (r.y1() - r.y0()).powi(2);
        let w = EXPLORE * self.used / diagonal_sq;
        if w.is_finite() { w } else { 0.0 }
    }
}

/// `x` ≥ 0 with all but the 6 highest bits of its mantissa cleared.
fn coarse(x: f64) -> f64 {
    f64::from_bits(x.to_bits() & !((1u64 << 46) - 1))
}

/// `min_size` and `max_size` as squared lengths an edge is compared with, and the
/// exploration term's weight.
#[derive(Debug, Clone, Copy)]
struct Scales {
    /// Edges shorter than this are never split: their halves would be below `min_size`.
    min_split_sq: f64,
    /// Edges longer than this go first.
    max_sq: f64,
    /// The weight on the squared length.
    explore: f64,
    /// Whether an encroached boundary edge goes first: with flips (`semi-recursive`).
    lens: bool,
}

impl Scales {
    fn of(params: &Params) -> Self {
        let min_split = 2.0 * params.min_size().unwrap_or(0.0);
        Self {
            min_split_sq: min_split * min_split,
            max_sq: params.max_size().map_or(f64::INFINITY, |m| m * m),
            explore: 0.0,
            lens: params.method() != Method::Recursive,
        }
    }
}

/// The queue with the lazy entries' count, so stale entries never outgrow the mesh.
struct Queue {
    heap: WorstEdgeQueue,
    len: usize,
    scales: Scales,
}

impl Queue {
    /// Queues the edge (p, q) at half-edge `h` with its value now, unless it is too short.
    #[inline]
    fn push(&mut self, mesh: &Mesh, grads: &[[f64; 2]], p: u32, q: u32, h: u32) {
        if let Some(value) = value(mesh, grads, self.scales, p.min(q), p.max(q), h) {
            self.heap.push(Candidate::new(value, p, q, h), mesh.vertices());
            self.len += 1;
        }
    }

    fn pop(&mut self, mesh: &Mesh) {
        self.heap.pop(mesh.vertices());
        self.len -= 1;
    }

    /// Every edge of `mesh` queued afresh.
    fn refill(&mut self, mesh: &Mesh, grads: &[[f64; 2]]) {
        self.heap = WorstEdgeQueue::new();
        self.len = 0;
        for edge in mesh.edges() {
            self.push(mesh, grads, edge.a, edge.b, edge.halfedge);
        }
    }

    /// A step queues about thirty entries for three new edges; past two entries an edge the
    /// queue is built again from the live edges (a rebuild every tenth of the vertices, as
    /// many pushes again), which bounds its memory at twice `variation`'s. The order is total,
    /// so the mesh is the same.
    fn compact(&mut self, mesh: &Mesh, grads: &[[f64; 2]]) {
        if self.len > mesh.num_halfedges() + 1024 {
            self.refill(mesh, grads);
        }
    }

    /// The worst queued edge that is still in the mesh with the value it was queued with, and
    /// its half-edge; entries for edges flipped away or valued again are dropped on the way.
    #[inline]
    fn settle(&mut self, mesh: &Mesh, grads: &[[f64; 2]]) -> Option<(Candidate, u32)> {
        loop {
            let &top = self.heap.peek()?;
            let (a, b) = (top.a, top.b);
            let live = mesh.edge_at(top.hint, a, b).or_else(|| mesh.find_edge(a, b));
            if let Some(e) = live
                && value(mesh, grads, self.scales, a, b, e)
                    .is_some_and(|v| v.to_bits() == { top.value }.to_bits())
            {
                return Some((top, e));
            }
            self.pop(mesh);
        }
    }
}

/// The value of the edge (a, b), a < b, at half-edge `h`: `None` below twice `min_size`; the
/// largest finite number above `max_size`, on a boundary edge its apex sees at more than
/// 120° (with flips), or where gradients overflow; else |(g_a − g_b)·(b − a)| / 8 (0 when
/// the two slopes differ by no more than a fit's rounding, 1e-9 of them, so on a plane every
/// edge ties) plus the exploration term.
///
/// The boundary rule is criterion `error`'s (`angles`): vertices crowding a side make needles
/// whose fits go wild (sin(10x)·cos(10y) had triangles of 1e-11° and 50× the error). Here it
/// is part of the edge's value, so that the queue, a function of the mesh alone, is all a run
/// needs to resume.
#[inline]
fn value(mesh: &Mesh, grads: &[[f64; 2]], scales: Scales, a: u32, b: u32, h: u32) -> Option<f64> {
    let (p, q) = (mesh.vertex(a), mesh.vertex(b));
    let (dx, dy) = (q.x - p.x, q.y - p.y);
    let len_sq = dx * dx + dy * dy;
    if len_sq < scales.min_split_sq {
        return None;
    }
    let (ga, gb) = (grads[a as usize], grads[b as usize]);
    let (sa, sb) = (ga[0] * dx + ga[1] * dy, gb[0] * dx + gb[1] * dy);
    let bend = (sa - sb).abs() * 0.125;
    let bend = if bend <= 1.25e-10 * (sa.abs() + sb.abs()) { 0.0 } else { bend };
    let v = bend + scales.explore * len_sq;
    let first = len_sq > scales.max_sq || !v.is_finite() || (scales.lens && lens_encroached(mesh, h));
    Some(if first { f64::MAX } else { v })
}

/// z at the midpoint of half-edge `e`'s edge on the cubic its ends' values and gradients
/// define: the chord's mean plus (g_p − g_q)·(q − p) / 8, or the mean where that overflows.
fn predicted(mesh: &Mesh, grads: &[[f64; 2]], e: u32) -> f64 {
    let (p, q) = (mesh.origin(e), mesh.dest(e));
    let (a, b) = (mesh.vertex(p), mesh.vertex(q));
    let (ga, gb) = (grads[p as usize], grads[q as usize]);
    let mean = 0.5 * (a.z + b.z);
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let bent = mean + ((ga[0] * dx + ga[1] * dy) - (gb[0] * dx + gb[1] * dy)) * 0.125;
    if bent.is_finite() { bent } else { mean }
}

/// Neighbours a vertex's fit needs: five unknowns. A vertex with fewer (a corner, some on the
/// sides) fits over its neighbours' neighbours too.
const FIT_POINTS: usize = 5;

/// Gradients as the quadratic least-squares fit around each vertex gives them, with the
/// scratch a fit gathers its points in (reused, so a step does not allocate).
struct Gradients {
    at: Vec<[f64; 2]>,
    ring: Vec<u32>,
}

impl Gradients {
    fn new(mesh: &Mesh, capacity: usize) -> Self {
        let mut this = Self { at: Vec::with_capacity(capacity), ring: Vec::with_capacity(32) };
        for v in 0..mesh.num_vertices() as u32 {
            let g = this.fit(mesh, v);
            this.at.push(g);
        }
        this
    }

    /// The gradient at `v`: of the quadratic through z_v nearest, in least squares, to z at
    /// the vertices around it. Exact for a quadratic F wherever `v` is, on a side or a corner
    /// too, where a mean of the triangles' gradients leans inward by half a triangle. A fit
    /// the points cannot determine (too few, or on one conic through `v`) falls back to the
    /// area-weighted mean of the triangles' gradients.
    fn fit(&mut self, mesh: &Mesh, v: u32) -> [f64; 2] {
        let ring = &mut self.ring;
        ring.clear();
        mesh.for_each_neighbour(v, |w, _| ring.push(w));
        if ring.len() < FIT_POINTS {
            for i in 0..ring.len() {
                mesh.for_each_neighbour(ring[i], |w, _| {
                    if w != v && !ring.contains(&w) {
                        ring.push(w);
                    }
                });
            }
        }
        quadratic_fit(mesh, v, ring).unwrap_or_else(|| mean_gradient(mesh, v))
    }
}

/// Whether `v` fits over its neighbours' neighbours, so that a change two rings away moves
/// its gradient.
fn fits_wide(mesh: &Mesh, v: u32) -> bool {
    let mut n = 0;
    mesh.for_each_neighbour(v, |_, _| n += 1);
    n < FIT_POINTS
}

/// The gradient of the quadratic q with q(v) = z_v that fits z at `points` best, in
/// coordinates scaled by the farthest point so the normal equations are well scaled.
fn quadratic_fit(mesh: &Mesh, v: u32, points: &[u32]) -> Option<[f64; 2]> {
    let o = mesh.vertex(v);
    let scale = points
        .iter()
        .map(|&w| (mesh.vertex(w).x - o.x).abs().max((mesh.vertex(w).y - o.y).abs()))
        .fold(0.0, f64::max);
    if points.len() < FIT_POINTS || scale <= 0.0 {
        return None;
    }
    // Normal equations AᵀA c = Aᵀz of the rows (u, w, u²/2, uw, w²/2), the upper triangle.
    let (mut ata, mut atz) = ([[0.0; 5]; 5], [0.0; 5]);
    for &p in points {
        let q = mesh.vertex(p);
        let (u, w) = ((q.x - o.x) / scale, (q.y - o.y) / scale);
        let row = [u, w, 0.5 * u * u, u * w, 0.5 * w * w];
        for i in 0..5 {
            for j in i..5 {
                ata[i][j] += row[i] * row[j];
            }
            atz[i] += row[i] * (q.z - o.z);
        }
    }
    let c = solve_spd(ata, atz)?;
    let g = [c[0] / scale, c[1] / scale];
    (g[0].is_finite() && g[1].is_finite()).then_some(g)
}

/// Solves the 5 × 5 symmetric positive definite system whose upper triangle is `a` by
/// Cholesky; `None` when a pivot falls below 1e-10 of the largest diagonal entry. By hand: a
/// crate's dense path would allocate on the engine's hottest loop, and this fixed sequence of
/// scalar operations gives the same bits on every machine, as the mesh must.
fn solve_spd(mut a: [[f64; 5]; 5], mut b: [f64; 5]) -> Option<[f64; 5]> {
    let floor = 1e-10 * (0..5).map(|i| a[i][i]).fold(0.0, f64::max);
    // a = Uᵀ U, U written over the upper triangle.
    for k in 0..5 {
        let pivot = a[k][k] - (0..k).map(|i| a[i][k] * a[i][k]).sum::<f64>();
        if pivot.is_nan() || pivot <= floor {
            return None;
        }
        let d = pivot.sqrt();
        a[k][k] = d;
        for j in k + 1..5 {
            a[k][j] = (a[k][j] - (0..k).map(|i| a[i][k] * a[i][j]).sum::<f64>()) / d;
        }
    }
    for k in 0..5 {
        b[k] = (b[k] - (0..k).map(|i| a[i][k] * b[i]).sum::<f64>()) / a[k][k];
    }
    for k in (0..5).rev() {
        b[k] = (b[k] - (k + 1..5).map(|j| a[k][j] * b[j]).sum::<f64>()) / a[k][k];
    }
    Some(b)
}

/// The area-weighted mean of the gradients of the triangles around `v`: Σ 2A·∇ / Σ 2A, where
/// 2A·∇ of a triangle is a cross product of its sides, so no division but the last.
fn mean_gradient(mesh: &Mesh, v: u32) -> [f64; 2] {
    let o = mesh.vertex(v);
    let (mut gx, mut gy, mut det) = (0.0, 0.0, 0.0);
    mesh.for_each_neighbour(v, |_, h| {
        // On the boundary a fan's last edge is met entering v, in a triangle already seen.
        if mesh.origin(h) != v {
            return;
        }
        let (b, c) = (mesh.vertex(mesh.dest(h)), mesh.vertex(mesh.apex(h)));
        let (x1, y1, z1) = (b.x - o.x, b.y - o.y, b.z - o.z);
        let (x2, y2, z2) = (c.x - o.x, c.y - o.y, c.z - o.z);
        gx += z1 * y2 - z2 * y1;
        gy += z2 * x1 - z1 * x2;
        det += x1 * y2 - x2 * y1;
    });
    [gx / det, gy / det]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Rect;
    use crate::refine::{Criterion, Method, Observer, Params, StopReason, dense_max_error, refine};

    fn params(n: usize, method: Method) -> crate::refine::ParamsBuilder {
        Params::builder(n).criterion(Criterion::Curvature).method(method)
    }

    #[test]
    fn the_gradient_of_a_plane_is_its_slope_at_every_vertex_and_no_edge_bends() {
        let plane = |x: f64, y: f64| 3.0 * x - 2.0 * y + 1.0;
        let p = params(60, Method::SemiRecursive).build().unwrap();
        let result = refine(&plane, Rect::new(-1.0, 2.0, 0.0, 1.0).unwrap(), &p, &mut ()).unwrap();
        let mesh = &result.mesh;
        let mut grads = Gradients::new(mesh, 0);
        for v in 0..mesh.num_vertices() as u32 {
            let [gx, gy] = grads.fit(mesh, v);
            assert!((gx - 3.0).abs() < 1e-12 && (gy + 2.0).abs() < 1e-12, "vertex {v}: ({gx}, {gy})");
        }
        // Every value ties near 0, so the longest edges go first: the mesh spreads evenly.
        let longest = mesh.edges().map(|e| mesh.len_sq(e.halfedge)).fold(0.0, f64::max).sqrt();
        assert!(longest < 0.6, "{longest}");
    }

    #[test]
    fn one_evaluation_a_vertex_and_a_valid_mesh_for_both_methods() {
        let f = |x: f64, y: f64| (-40.0 * ((x - 0.3).powi(2) + (y - 0.6).powi(2))).exp();
        for method in [Method::Recursive, Method::SemiRecursive] {
            let p = params(800, method).build().unwrap();
            let result = refine(&f, Rect::unit(), &p, &mut ()).unwrap();
            result.mesh.check_invariants().unwrap();
            assert_eq!(result.stats.vertices, 800);
            assert_eq!(result.stats.evaluations, 800, "{method}");
            if method == Method::SemiRecursive {
                assert!(result.stats.delaunay);
            }
        }
    }

    #[test]
    fn on_a_smooth_peak_it_beats_the_papers_variation_at_equal_vertices() {
        // Franke's function: two peaks and a dip, the engine's usual test surface.
        let franke = |x: f64, y: f64| {
            0.75 * (-((9.0 * x - 2.0).powi(2) + (9.0 * y - 2.0).powi(2)) / 4.0).exp()
                + 0.75 * (-(9.0 * x + 1.0).powi(2) / 49.0 - (9.0 * y + 1.0) / 10.0).exp()
                + 0.5 * (-((9.0 * x - 7.0).powi(2) + (9.0 * y - 3.0).powi(2)) / 4.0).exp()
                - 0.2 * (-(9.0 * x - 4.0).powi(2) - (9.0 * y - 7.0).powi(2)).exp()
        };
        let error = |criterion| {
            let p = Params::builder(3000).criterion(criterion).build().unwrap();
            let result = refine(&franke, Rect::unit(), &p, &mut ()).unwrap();
            dense_max_error(&result.mesh, &franke, 401)
        };
        let (curvature, variation) = (error(Criterion::Curvature), error(Criterion::Variation));
        assert!(curvature < 0.7 * variation, "curvature {curvature:e}, variation {variation:e}");
    }

    #[test]
    fn max_size_splits_every_longer_edge_first() {
        let p = params(100_000, Method::SemiRecursive).max_size(0.1).tolerance(0.0).build().unwrap();
        let result = refine(&|_: f64, _: f64| 1.0, Rect::unit(), &p, &mut ()).unwrap();
        assert_eq!(result.stats.stop, StopReason::Tolerance);
        let mesh = &result.mesh;
        let longest = mesh.edges().map(|e| mesh.len_sq(e.halfedge)).fold(0.0, f64::max).sqrt();
        assert!(longest <= 0.1, "{longest}");
        assert!(mesh.num_vertices() < 400, "no edge is split once every edge is short enough");
    }

    /// Records the length of every edge the engine chose to split.
    #[derive(Default)]
    struct Chosen(Vec<f64>);

    impl Observer for Chosen {
        fn selected(&mut self, mesh: &Mesh, a: u32, b: u32) {
            self.0.push(mesh.point(a).distance_sq(mesh.point(b)).sqrt());
        }
    }

    #[test]
    fn min_size_keeps_a_kink_from_drawing_every_vertex() {
        // A cone's tip never stops bending: without min_size the budget keeps going there.
        let cone = |x: f64, y: f64| ((x - 0.31).powi(2) + (y - 0.47).powi(2)).sqrt();
        let near_tip =
            |mesh: &Mesh| mesh.vertices().iter().filter(|v| (v.x - 0.31).hypot(v.y - 0.47) < 0.05).count();
        let free =
            refine(&cone, Rect::unit(), &params(2000, Method::SemiRecursive).build().unwrap(), &mut ())
                .unwrap();
        assert!(near_tip(&free.mesh) > 100, "{}", near_tip(&free.mesh));
        let p = params(2000, Method::SemiRecursive).min_size(0.03).build().unwrap();
        let mut chosen = Chosen::default();
        let sized = refine(&cone, Rect::unit(), &p, &mut chosen).unwrap();
        assert_eq!(sized.stats.stop, StopReason::Exhausted);
        assert!(sized.stats.vertices < 2000 && near_tip(&sized.mesh) < 20, "{}", near_tip(&sized.mesh));
        assert!(!chosen.0.is_empty() && chosen.0.iter().all(|&len| len >= 0.06), "{:?}", chosen.0);
    }

    #[test]
    fn the_queue_compacts_without_changing_the_mesh() {
        // Compaction drops stale entries only: a run long enough to compact many times ends in
        // the mesh whose every step took the worst live edge, as a brute force finds it.
        let f = |x: f64, y: f64| (5.0 * x).sin() * (4.0 * y).cos();
        let p = params(400, Method::SemiRecursive).build().unwrap();
        let result = refine(&f, Rect::unit(), &p, &mut ()).unwrap();
        let replay = brute_force(&f, 400);
        assert_eq!(result.mesh.vertices(), replay.vertices());
    }

    /// The criterion without a queue: every step values every edge afresh.
    fn brute_force(f: &dyn Fn(f64, f64) -> f64, n: usize) -> Mesh {
        let rect = Rect::unit();
        let z = rect.corners().map(|p| f(p.x, p.y));
        let mut mesh = Mesh::new(rect, z);
        let p = params(n, Method::SemiRecursive).build().unwrap();
        let (mut scales, mut range) = (Scales::of(&p), Range::of(&mesh));
        scales.explore = range.explore(&mesh);
        let mut observer = ();
        let mut run = Run::new(&p, &mut observer, crate::refine::Floors::of_rect(rect));
        let mut field =
            |a: crate::geom::Vertex, b: crate::geom::Vertex| f(0.5 * (a.x + b.x), 0.5 * (a.y + b.y));
        while mesh.num_vertices() < n {
            let grads = Gradients::new(&mesh, 0).at;
            let vertices = mesh.vertices().to_vec();
            let worst = mesh
                .edges()
                .map(|e| {
                    Candidate::new(
                        value(&mesh, &grads, scales, e.a.min(e.b), e.a.max(e.b), e.halfedge).unwrap(),
                        e.a,
                        e.b,
                        e.halfedge,
                    )
                })
                .max_by(|x, y| x.cmp(y, &vertices))
                .unwrap();
            let h = mesh.find_edge(worst.a, worst.b).unwrap();
            let split =
                run.split_midpoint(&mut mesh, &mut Mid(&mut field), h, None, |_, _| {}).unwrap().unwrap();
            if range.widened(mesh.vertex(split.vertex).z) {
                scales.explore = range.explore(&mesh);
            }
        }
        mesh
    }

    /// A field from a closure of the edge's ends.
    struct Mid<'f, C>(&'f mut C);

    impl<C: FnMut(crate::geom::Vertex, crate::geom::Vertex) -> f64> Field for Mid<'_, C> {
        type Error = std::convert::Infallible;
        fn midpoint(
            &mut self,
            a: crate::geom::Vertex,
            b: crate::geom::Vertex,
            _m: crate::geom::Point,
        ) -> Result<f64, Self::Error> {
            Ok((self.0)(a, b))
        }
    }
}
