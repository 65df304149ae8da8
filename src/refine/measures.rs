//! Measures of a finished mesh: the variation V_n and an estimate of the error E_n.
//!
//! Kept out of the refinement loop: these walk the whole mesh once.

use super::angles::smallest_angle_cos_sq;
use crate::geom::{Mesh, Point, Vertex, raster};
use crate::source::{Grid, Surface};

/// V_n = max |zᵢ − zⱼ| over the edges (i, j) of the mesh.
///
/// V_n is not monotone in n: a midpoint value can open a larger gap than the edge it split.
///
/// Swept over the triangles, which see every edge (an interior one twice, which a maximum
/// does not mind, and |zᵢ − zⱼ| = |zⱼ − zᵢ| to the bit): the half-edges in order, with no
/// twin to test or next half-edge to find, as a walk over the edges has.
pub fn variation(mesh: &Mesh) -> f64 {
    let z = |v: u32| mesh.vertex(v).z;
    let gap = |[a, b, c]: [u32; 3]| {
        let (za, zb, zc) = (z(a), z(b), z(c));
        (za - zb).abs().max((zb - zc).abs()).max((zc - za).abs())
    };
    mesh.triangles().map(gap).fold(0.0, f64::max)
}

/// How well the mesh approximates F, estimated by sampling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorEstimate {
    /// E_n ≈ max |F − F_n| over the samples.
    pub max_error: f64,
    /// Root mean square of F − F_n, each triangle weighted by its area (by node for a grid).
    pub rms_error: f64,
    /// The smallest interior angle of any triangle, in degrees.
    pub min_angle_deg: f64,
    /// How many points were sampled.
    pub samples: u64,
}

/// Barycentric weights ×4 of the order-4 lattice points that are not corners: 3 inside each
/// edge, in the order of the triangle's half-edges (a→b, b→c, c→a), then 3 inside it. Both
/// the E_n estimate and the error criterion sample these.
pub(super) const LATTICE: [[u8; 3]; 12] = [
    [3, 1, 0],
    [2, 2, 0],
    [1, 3, 0],
    [0, 3, 1],
    [0, 2, 2],
    [0, 1, 3],
    [1, 0, 3],
    [2, 0, 2],
    [3, 0, 1],
    [2, 1, 1],
    [1, 2, 1],
    [1, 1, 2],
];

/// The lattice point with weights `[i, j, k]` (×4) of triangle (a, b, c), and F_n there.
///
/// On an edge the third weight is zero and IEEE addition commutes, so both triangles of the
/// edge compute the same bits: the error criterion relies on that to share edge samples.
#[inline]
pub(super) fn lattice_point([a, b, c]: &[Vertex; 3], [i, j, k]: [u8; 3]) -> (Point, f64) {
    let (wa, wb, wc) = (f64::from(i) * 0.25, f64::from(j) * 0.25, f64::from(k) * 0.25);
    let p = Point::new(wa * a.x + wb * b.x + wc * c.x, wa * a.y + wb * b.y + wc * c.y);
    (p, wa * a.z + wb * b.z + wc * c.z)
}

/// Estimates E_n = max |F − F_n|, where F_n is the piecewise linear interpolant on `mesh`.
///
/// An expression is sampled on a fixed barycentric lattice of order 4 in every triangle (the
/// 9 points inside its edges and 3 inside it; F_n equals F at the corners). A grid is compared
/// at every grid node exactly, each node once. Samples where F is not finite are skipped.
pub fn estimate_error<S: Surface + ?Sized>(mesh: &Mesh, surface: &S) -> ErrorEstimate {
    let min_angle_deg = min_angle_deg(mesh);
    let (max_error, rms_error, samples) = match surface.grid() {
        Some(grid) => grid_error(mesh, grid),
        None => lattice_error(mesh, surface),
    };
    ErrorEstimate { max_error, rms_error, min_angle_deg, samples }
}

fn corners(mesh: &Mesh, t: usize) -> [(Point, f64); 3] {
    mesh.triangle(t).map(|v| {
        let v = mesh.vertex(v);
        (v.point(), v.z)
    })
}

/// The smallest interior angle of any triangle, in degrees.
///
/// The triangle is found by cos² of its smallest angle, which takes no trigonometry (three
/// `atan2` per triangle were a third of a grid run's final pass), and only its angles are
/// measured. Where two triangles' angles tie within rounding either may be taken: their
/// values differ in the last bits at most.
pub(super) fn min_angle_deg(mesh: &Mesh) -> f64 {
    let cos_sq = |t: usize| {
        let [a, b, c] = mesh.triangle(t).map(|v| mesh.point(v));
        // A triangle with coincident corners (never in a valid mesh) gives NaN: it is 0°.
        let cos_sq = smallest_angle_cos_sq(a, b, c);
        if cos_sq.is_nan() { f64::INFINITY } else { cos_sq }
    };
    let smallest = (0..mesh.num_triangles())
        .map(|t| (cos_sq(t), t))
        .reduce(|best, t| if t.0 > best.0 { t } else { best });
    smallest.map_or(f64::INFINITY, |(_, t)| min_angle(mesh, t)).to_degrees()
}

fn min_angle(mesh: &Mesh, t: usize) -> f64 {
    let [(a, _), (b, _), (c, _)] = corners(mesh, t);
    let angle = |p: Point, q: Point, r: Point| {
        let (u, v) = ((q.x - p.x, q.y - p.y), (r.x - p.x, r.y - p.y));
        (u.0 * v.1 - u.1 * v.0).abs().atan2(u.0 * v.0 + u.1 * v.1)
    };
    angle(a, b, c).min(angle(b, c, a)).min(angle(c, a, b))
}

/// Triangles whose lattice points go through F in one call: 8 × 12 = 96 points, three full
/// batches of the compiled expression where one triangle's 12 were a batch short of its
/// width (`benches/expression.rs`).
const GROUP: usize = 8;

fn lattice_error<S: Surface + ?Sized>(mesh: &Mesh, surface: &S) -> (f64, f64, u64) {
    const POINTS: usize = GROUP * LATTICE.len();
    let (mut max, mut weighted_sq, mut area_sum, mut samples) = (0.0f64, 0.0, 0.0, 0u64);
    let (mut points, mut linear, mut values) = ([Point::new(0.0, 0.0); POINTS], [0.0; POINTS], [0.0; POINTS]);
    let mut areas = [0.0; GROUP];
    let n = mesh.num_triangles();
    for first in (0..n).step_by(GROUP) {
        let group = first..n.min(first + GROUP);
        let used = group.len() * LATTICE.len();
        for (k, t) in group.enumerate() {
            let corners = mesh.triangle(t).map(|v| mesh.vertex(v));
            for (i, w) in LATTICE.into_iter().enumerate() {
                (points[k * LATTICE.len() + i], linear[k * LATTICE.len() + i]) = lattice_point(&corners, w);
            }
            let [a, b, c] = corners.map(Vertex::point);
            areas[k] = 0.5 * ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
        }
        surface.eval_many(&points[..used], &mut values[..used]);
        // Triangle by triangle, in order, as if each had been sampled alone.
        let triangles = values[..used].chunks(LATTICE.len()).zip(linear.chunks(LATTICE.len()));
        for ((values, linear), &area) in triangles.zip(&areas) {
            let (mut sum_sq, mut count) = (0.0, 0u32);
            for (exact, l) in values.iter().zip(linear).filter(|(v, _)| v.is_finite()) {
                let err = (exact - l).abs();
                max = max.max(err);
                sum_sq += err * err;
                count += 1;
            }
            if count > 0 {
                weighted_sq += area * sum_sq / f64::from(count);
                area_sum += area;
                samples += u64::from(count);
            }
        }
    }
    let rms = if area_sum > 0.0 { (weighted_sq / area_sum).sqrt() } else { 0.0 };
    (max, rms, samples)
}

/// Compares every grid node once, visiting the nodes each triangle covers.
fn grid_error(mesh: &Mesh, grid: &Grid) -> (f64, f64, u64) {
    let (mut max, mut sum_sq, mut samples) = (0.0f64, 0.0, 0u64);
    let to_grid = |p: Point| {
        let (u, v) = grid.to_grid(p);
        Point::new(u, v)
    };
    for_each_covered_node(mesh, grid.nx(), grid.ny(), to_grid, |i, j, linear| {
        let err = (grid.value(i, j) - linear).abs();
        max = max.max(err);
        sum_sq += err * err;
        samples += 1;
    });
    let rms = if samples > 0 { (sum_sq / samples as f64).sqrt() } else { 0.0 };
    (max, rms, samples)
}

/// Calls `visit(i, j, F_n)` once for every node (i, j) of an `nx × ny` grid that a triangle
/// of `mesh` covers, `to_grid` giving a point's position in grid units.
fn for_each_covered_node(
    mesh: &Mesh,
    nx: usize,
    ny: usize,
    to_grid: impl Fn(Point) -> Point,
    mut visit: impl FnMut(usize, usize, f64),
) {
    // Nodes on an edge belong to both its triangles: a bit per node keeps them to one visit.
    let mut seen = vec![0u64; (nx * ny).div_ceil(64)];
    for t in 0..mesh.num_triangles() {
        let corners = corners(mesh, t);
        let in_grid = corners.map(|(p, _)| to_grid(p));
        let Some(plane) = raster::Plane::new(in_grid, corners.map(|(_, z)| z)) else {
            continue;
        };
        raster::for_each_span(in_grid, nx, ny, |j, i0, i1| {
            for (i, linear) in (i0..=i1).zip(plane.row(i0, j)) {
                let index = j * nx + i;
                if seen[index / 64] & (1 << (index % 64)) == 0 {
                    seen[index / 64] |= 1 << (index % 64);
                    visit(i, j, linear);
                }
            }
        });
    }
}

/// E_max on a dense sample: an `n × n` grid over the rectangle plus every edge midpoint and
/// centroid of the mesh (F_n equals F at the vertices), each grid point compared once. The
/// measure of the quality table (docs/quality.md); far costlier than [`estimate_error`].
pub fn dense_max_error<S: Surface + ?Sized>(mesh: &Mesh, surface: &S, n: usize) -> f64 {
    let r = mesh.rect();
    let (hx, hy) = ((r.x1() - r.x0()) / (n - 1) as f64, (r.y1() - r.y0()) / (n - 1) as f64);
    let mut max = 0.0f64;
    let mut compare = |p: Point, linear: f64| {
        let exact = surface.eval(p);
        if exact.is_finite() {
            max = max.max((exact - linear).abs());
        }
    };
    for edge in mesh.edges() {
        let (p, q) = (mesh.vertex(edge.a), mesh.vertex(edge.b));
        compare(p.point().midpoint(q.point()), 0.5 * (p.z + q.z));
    }
    for t in 0..mesh.num_triangles() {
        let [(a, za), (b, zb), (c, zc)] = corners(mesh, t);
        compare(Point::new((a.x + b.x + c.x) / 3.0, (a.y + b.y + c.y) / 3.0), (za + zb + zc) / 3.0);
    }
    let to_grid = |p: Point| Point::new((p.x - r.x0()) / hx, (p.y - r.y0()) / hy);
    for_each_covered_node(mesh, n, n, to_grid, |i, j, linear| {
        compare(Point::new(r.x0() + i as f64 * hx, r.y0() + j as f64 * hy), linear);
    });
    max
}
