//! Point location in a finished mesh, and F_n (the piecewise linear surrogate) at any point.
//!
//! A uniform grid of buckets over the rectangle holds, for each bucket, a triangle that
//! contains its centre. A query starts there and walks across edges toward the point (a
//! visibility walk with exact orientation tests), which takes a step or two when buckets are
//! about the size of triangles. The walk's first edge rotates with the step count, so it also
//! ends in meshes that are not Delaunay (the recursive method's), where a walk that always
//! tries edges in one order can cycle (Devillers, Pion and Teillaud, "Walking in a
//! triangulation", 2002); a walk that still has not arrived after many steps falls back to a
//! scan, so every answer is exact.

use super::RunResult;
use crate::geom::predicates::{Orientation, orientation, signed_area_x2};
// `signed_area_x2` is robust's orient2d: its sign is exact, so the walk decides with it.
use crate::geom::{NONE, Point, Vertex};

/// Walk steps after which a query gives up walking and scans (never reached in practice).
const MAX_WALK: usize = 4096;

/// Batches from this size on are sorted by bucket before they are evaluated.
const SORT_FROM: usize = 4096;

/// A bucket grid over one [`RunResult`]'s triangles, each with its corners and neighbours,
/// built once and shared.
#[derive(Debug, Clone)]
pub struct Locator {
    /// [x0, x1, y0, y1] of the mesh.
    bounds: [f64; 4],
    cols: usize,
    rows: usize,
    /// A triangle containing each bucket's centre, row by row.
    buckets: Vec<u32>,
    /// Each triangle's corners and neighbours side by side: a walk step reads one triangle's
    /// two cache lines, not three vertices, a triangle and its twins from four arrays.
    triangles: Vec<Triangle>,
    /// The mesh's index of each stored triangle.
    ids: Vec<u32>,
}

/// A triangle as a walk reads it.
#[derive(Debug, Clone, Copy)]
struct Triangle {
    /// x, y and z of each corner, counter-clockwise.
    corners: [Vertex; 3],
    /// For edge k (corner k to corner k + 1), the half-edge 3t' + k' running the other way
    /// in triangle t', or [`NONE`] on the boundary.
    twins: [u32; 3],
}

impl Triangle {
    fn points(&self) -> [Point; 3] {
        self.corners.map(Vertex::point)
    }
}

impl Locator {
    /// Indexes `mesh`: about one bucket per triangle.
    pub fn new(mesh: &RunResult) -> Self {
        let bounds = mesh.bounds();
        let triangles = mesh.triangles.len().max(1);
        let (w, h) = (bounds[1] - bounds[0], bounds[3] - bounds[2]);
        // Where the criterion packs triangles tight, a bucket still holds many: more buckets
        // shorten those walks for 4 bytes each.
        let target = triangles as f64;
        let cols = ((target * w / h).sqrt().ceil() as usize).clamp(1, 1 << 14);
        let rows = ((target / cols as f64).ceil() as usize).clamp(1, 1 << 14);
        let mut locator = Self {
            bounds,
            cols,
            rows,
            buckets: vec![NONE; cols * rows],
            triangles: Vec::new(),
            ids: Vec::new(),
        };
        // Stored in the order of their centres' buckets, so that nearby queries read nearby
        // memory; ties keep the mesh's order.
        let corners = |t: usize| mesh.triangles[t].map(|v| mesh.vertices[v as usize]);
        let centre =
            |c: [Vertex; 3]| Point::new((c[0].x + c[1].x + c[2].x) / 3.0, (c[0].y + c[1].y + c[2].y) / 3.0);
        // Each key computed once: `sort_by_key` would recompute it at every comparison.
        let mut keyed: Vec<(usize, u32)> = (0..mesh.triangles.len() as u32)
            .map(|t| (locator.bucket_of(centre(corners(t as usize))), t))
            .collect();
        keyed.sort_unstable();
        let ids: Vec<u32> = keyed.into_iter().map(|(_, t)| t).collect();
        let mut slot = vec![0u32; ids.len()];
        for (new, &old) in ids.iter().enumerate() {
            slot[old as usize] = new as u32;
        }
        let twins = twins(mesh);
        let moved = |h: u32| if h == NONE { NONE } else { 3 * slot[(h / 3) as usize] + h % 3 };
        locator.triangles = ids
            .iter()
            .map(|&t| {
                let t = t as usize;
                Triangle { corners: corners(t), twins: [0, 1, 2].map(|k| moved(twins[3 * t + k])) }
            })
            .collect();
        locator.ids = ids;
        locator.fill();
        locator
    }

    /// Bytes the index takes, for a cache's weigher.
    pub fn num_bytes(&self) -> usize {
        size_of::<Self>()
            + 4 * (self.buckets.len() + self.ids.len())
            + size_of::<Triangle>() * self.triangles.len()
    }

    fn bucket_of(&self, p: Point) -> usize {
        let [x0, x1, y0, y1] = self.bounds;
        let col = ((p.x - x0) / (x1 - x0) * self.cols as f64) as usize;
        let row = ((p.y - y0) / (y1 - y0) * self.rows as f64) as usize;
        row.min(self.rows - 1) * self.cols + col.min(self.cols - 1)
    }

    fn centre(&self, col: usize, row: usize) -> Point {
        let [x0, x1, y0, y1] = self.bounds;
        Point::new(
            x0 + (col as f64 + 0.5) * (x1 - x0) / self.cols as f64,
            y0 + (row as f64 + 0.5) * (y1 - y0) / self.rows as f64,
        )
    }

    /// Gives each bucket the first triangle, by index, that contains its centre.
    fn fill(&mut self) {
        let [x0, x1, y0, y1] = self.bounds;
        let (sx, sy) = (self.cols as f64 / (x1 - x0), self.rows as f64 / (y1 - y0));
        for t in 0..self.triangles.len() {
            let p = self.triangles[t].points();
            let (lo_x, hi_x) = (p[0].x.min(p[1].x).min(p[2].x), p[0].x.max(p[1].x).max(p[2].x));
            let (lo_y, hi_y) = (p[0].y.min(p[1].y).min(p[2].y), p[0].y.max(p[1].y).max(p[2].y));
            // Buckets whose centres may lie in the bounding box (centre k sits at k + 0.5).
            let cols = span((lo_x - x0) * sx, (hi_x - x0) * sx, self.cols);
            let rows = span((lo_y - y0) * sy, (hi_y - y0) * sy, self.rows);
            for row in rows {
                for col in cols.clone() {
                    let b = row * self.cols + col;
                    if self.buckets[b] == NONE && contains(p, self.centre(col, row)) {
                        self.buckets[b] = t as u32;
                    }
                }
            }
        }
    }

    /// The triangle that contains `p` (on an edge: one of its two), or `None` outside the
    /// mesh or for a non-finite point.
    pub fn locate(&self, p: Point) -> Option<u32> {
        self.find(p).map(|(t, _)| self.ids[t as usize])
    }

    /// F_n(p): the value of the mesh's linear interpolant at `p`, `None` outside the mesh.
    pub fn value(&self, p: Point) -> Option<f64> {
        let (t, d) = self.find(p)?;
        let z = self.triangles[t as usize].corners.map(|c| c.z);
        // The walk's last three orientations are the barycentric weights (twice the areas of
        // the sub-triangles facing each corner): edge k faces corner k + 2.
        let w = [d[1], d[2], d[0]];
        // At a vertex, its own value exactly ((w·z)/w can be off by an ulp).
        match w {
            [_, 0.0, 0.0] => return Some(z[0]),
            [0.0, _, 0.0] => return Some(z[1]),
            [0.0, 0.0, _] => return Some(z[2]),
            _ => {}
        }
        let sum = w[0] + w[1] + w[2];
        Some((w[0] * z[0] + w[1] * z[1] + w[2] * z[2]) / sum)
    }

    /// F_n at each of `points`, NaN outside the mesh. Large batches are evaluated bucket by
    /// bucket (a counting sort of the points by bucket) and written back in the given order:
    /// points that arrive scattered then share cache lines as a raster's do, which on a
    /// 10^5-vertex mesh is the difference between waiting on memory and not (`cargo bench
    /// --bench evaluate`). The values are the same either way.
    pub fn values(&self, points: &[Point]) -> Vec<f64> {
        let one = |p: Point| self.value(p).unwrap_or(f64::NAN);
        if points.len() < SORT_FROM {
            return points.iter().map(|&p| one(p)).collect();
        }
        let [x0, x1, y0, y1] = self.bounds;
        let inside = |p: &Point| x0 <= p.x && p.x <= x1 && y0 <= p.y && p.y <= y1;
        // Counting sort: bucket of each point (outside ones last), then the starts of buckets.
        let nb = self.buckets.len();
        let keys: Vec<u32> =
            points.iter().map(|p| if inside(p) { self.bucket_of(*p) as u32 } else { nb as u32 }).collect();
        let mut starts = vec![0u32; nb + 2];
        for &k in &keys {
            starts[k as usize + 1] += 1;
        }
        for b in 1..starts.len() {
            starts[b] += starts[b - 1];
        }
        let mut order = vec![0u32; points.len()];
        for (i, &k) in keys.iter().enumerate() {
            order[starts[k as usize] as usize] = i as u32;
            starts[k as usize] += 1;
        }
        let mut out = vec![f64::NAN; points.len()];
        for &i in &order {
            out[i as usize] = one(points[i as usize]);
        }
        out
    }

    /// The triangle containing `p` and the orientation determinant of `p` against each of its
    /// edges (all at least zero, exact in sign), by walking from `p`'s bucket.
    /// Walks the segment `a`–`b` through the mesh, calling `f` with each triangle it crosses
    /// (the mesh's index) and the fraction of the segment inside it, in order; the fractions
    /// sum to 1 (to rounding). False when the segment leaves the mesh.
    ///
    /// In the triangle holding the walk's point, the exit is where the segment first leaves
    /// the half-plane of an edge that b lies beyond (exact orientations pick the edges; the
    /// crossing parameter is the ratio of the two ends' signed areas). The next triangle is
    /// the one the walk of [`Locator::locate`] finds a hair past the exit (10⁻¹² of the
    /// segment, also the least step), so a piece that short near a vertex may be credited to a
    /// neighbour. Where needles a hair wide hold the walk to such steps, it clips the segment
    /// against every triangle instead.
    pub fn crossings(&self, a: Point, b: Point, mut f: impl FnMut(u32, f64)) -> bool {
        const HAIR: f64 = 1e-12;
        let at = |s: f64| Point::new(a.x + s * (b.x - a.x), a.y + s * (b.y - a.y));
        let Some((mut t, _)) = self.find(a) else { return false };
        let (mut from, mut pieces, mut hairs) = (0.0, Vec::new(), 0);
        loop {
            let c = self.triangles[t as usize].points();
            if contains(c, b) {
                pieces.push((self.ids[t as usize], 1.0 - from));
                break;
            }
            let exit = self.exit(t, a, b).max(from + HAIR).min(1.0);
            hairs = if exit - from <= 2.0 * HAIR { hairs + 1 } else { 0 };
            if hairs > 64 {
                return self.clip(a, b, f);
            }
            pieces.push((self.ids[t as usize], exit - from));
            from = exit;
            if from >= 1.0 {
                break;
            }
            // Along the boundary the hair's rounding may step outside: the exit itself is in.
            let past = self.find(at((from + HAIR).min(1.0))).or_else(|| self.find(at(from)));
            let Some((next, _)) = past else { return self.clip(a, b, f) };
            t = next;
        }
        for (t, fraction) in pieces {
            f(t, fraction);
        }
        true
    }

    /// Where the segment `a`–`b` leaves stored triangle `t`: the least crossing parameter of
    /// the edges b lies beyond (1 when none).
    fn exit(&self, t: u32, a: Point, b: Point) -> f64 {
        let c = self.triangles[t as usize].points();
        let mut exit = 1.0f64;
        for k in 0..3 {
            let beyond = signed_area_x2(c[k], c[(k + 1) % 3], b);
            if beyond < 0.0 {
                let here = signed_area_x2(c[k], c[(k + 1) % 3], a);
                exit = exit.min(here / (here - beyond));
            }
        }
        exit
    }

    /// [`Locator::crossings`] by clipping the segment against every triangle (Cyrus–Beck on
    /// the three half-planes), in the order the pieces start. A segment along an interior
    /// edge lies in both its triangles: each takes half. False unless the pieces cover it.
    fn clip(&self, a: Point, b: Point, mut f: impl FnMut(u32, f64)) -> bool {
        let mut pieces = Vec::new();
        for (t, triangle) in self.triangles.iter().enumerate() {
            let c = triangle.points();
            let (mut lo, mut hi, mut share) = (0.0f64, 1.0f64, 1.0);
            for k in 0..3 {
                let here = signed_area_x2(c[k], c[(k + 1) % 3], a);
                let beyond = signed_area_x2(c[k], c[(k + 1) % 3], b);
                if here == 0.0 && beyond == 0.0 && triangle.twins[k] != NONE {
                    share = 0.5;
                }
                match (here >= 0.0, beyond >= 0.0) {
                    (true, true) => {}
                    (false, false) => hi = -1.0,
                    (true, false) => hi = hi.min(here / (here - beyond)),
                    (false, true) => lo = lo.max(here / (here - beyond)),
                }
            }
            if lo < hi {
                pieces.push((lo, self.ids[t], share * (hi - lo)));
            }
        }
        pieces.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
        let covered: f64 = pieces.iter().map(|p| p.2).sum();
        if (covered - 1.0).abs() > 1e-9 {
            return false;
        }
        for (_, t, fraction) in pieces {
            f(t, fraction);
        }
        true
    }

    fn find(&self, p: Point) -> Option<(u32, [f64; 3])> {
        let [x0, x1, y0, y1] = self.bounds;
        if !(x0 <= p.x && p.x <= x1 && y0 <= p.y && p.y <= y1) {
            return None;
        }
        let start = self.buckets[self.bucket_of(p)];
        let mut t = if start == NONE { 0 } else { start };
        'walk: for step in 0..MAX_WALK {
            let triangle = &self.triangles[t as usize];
            let corners = triangle.points();
            let mut d = [0.0; 3];
            for j in 0..3 {
                let k = (step + j) % 3;
                d[k] = signed_area_x2(corners[k], corners[(k + 1) % 3], p);
                if d[k] < 0.0 {
                    let twin = triangle.twins[k];
                    if twin == NONE {
                        return None;
                    }
                    t = twin / 3;
                    continue 'walk;
                }
            }
            return Some((t, d));
        }
        let t =
            (0..self.triangles.len() as u32).find(|&t| contains(self.triangles[t as usize].points(), p))?;
        let c = self.triangles[t as usize].points();
        Some((t, [0, 1, 2].map(|k| signed_area_x2(c[k], c[(k + 1) % 3], p).max(0.0))))
    }
}

/// Whether the counter-clockwise triangle `p` contains `q`, its edges included.
fn contains(p: [Point; 3], q: Point) -> bool {
    (0..3).all(|k| orientation(p[k], p[(k + 1) % 3], q) != Orientation::Clockwise)
}

/// The bucket indices k with centre k + 0.5 in [lo, hi], clamped to 0..n.
fn span(lo: f64, hi: f64, n: usize) -> std::ops::Range<usize> {
    let first = (lo - 0.5).ceil().max(0.0) as usize;
    let last = ((hi - 0.5).floor() + 1.0).clamp(0.0, n as f64) as usize;
    first.min(n)..last.max(first.min(n))
}

/// The twin of every half-edge, found by sorting the directed edges once.
fn twins(mesh: &RunResult) -> Vec<u32> {
    let key = |a: u32, b: u32| (u64::from(a) << 32) | u64::from(b);
    let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * mesh.triangles.len());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            edges.push((key(tri[k], tri[(k + 1) % 3]), (3 * t + k) as u32));
        }
    }
    edges.sort_unstable();
    let mut twins = vec![NONE; edges.len()];
    for &(k, e) in &edges {
        let (a, b) = ((k >> 32) as u32, k as u32);
        if let Ok(i) = edges.binary_search_by_key(&key(b, a), |&(k, _)| k) {
            twins[e as usize] = edges[i].1;
        }
    }
    twins
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::{Criterion, Method, Params, refine};
    use crate::result::testing::sample;
    use proptest::prelude::*;

    fn point(mesh: &RunResult, v: u32) -> Point {
        mesh.vertices[v as usize].point()
    }

    /// The naive oracle: the first triangle, by index, that contains `p`.
    fn scan(mesh: &RunResult, p: Point) -> Option<u32> {
        (0..mesh.triangles.len() as u32)
            .find(|&t| contains(mesh.triangles[t as usize].map(|v| point(mesh, v)), p))
    }

    fn recursive_sample(n: usize) -> RunResult {
        let f = |x: f64, y: f64| (12.0 * x).sin() * (9.0 * y).cos();
        let params =
            Params::builder(n).method(Method::Recursive).criterion(Criterion::Variation).build().unwrap();
        refine(&f, crate::geom::Rect::unit(), &params, &mut ()).unwrap().into()
    }

    proptest! {
        #[test]
        fn located_triangles_contain_the_point_and_agree_with_a_scan_on_inside_and_outside(
            x in -1.5f64..2.5, y in -0.5f64..1.5,
        ) {
            for mesh in [sample(700, Criterion::Error), recursive_sample(700)] {
                let locator = Locator::new(&mesh);
                let p = Point::new(x, y);
                let found = locator.locate(p);
                prop_assert_eq!(found.is_some(), scan(&mesh, p).is_some());
                if let Some(t) = found {
                    prop_assert!(contains(mesh.triangles[t as usize].map(|v| point(&mesh, v)), p));
                }
            }
        }
    }

    proptest! {
        /// A segment's pieces cover it, in order, each in the triangle named, also through
        /// vertices (segments between vertices) and on recursive meshes.
        #[test]
        fn a_segments_crossings_cover_it_with_pieces_inside_their_triangles(
            from in 0usize..700, to in 0usize..700, u in 0.0f64..=1.0, v in 0.0f64..=1.0, at_vertices: bool,
        ) {
            for mesh in [sample(700, Criterion::Error), recursive_sample(700)] {
                let locator = Locator::new(&mesh);
                let n = mesh.vertices.len();
                let (a, b) = if at_vertices {
                    (point(&mesh, (from % n) as u32), point(&mesh, (to % n) as u32))
                } else {
                    let [x0, x1, y0, y1] = mesh.bounds();
                    (Point::new(x0 + u * (x1 - x0), y0 + v * (y1 - y0)), point(&mesh, (to % n) as u32))
                };
                let mut pieces = Vec::new();
                prop_assert!(locator.crossings(a, b, |t, fraction| pieces.push((t, fraction))));
                // The walk's pieces telescope to 1 to rounding; the clip it falls back on meets
                // its neighbours' crossings, each rounded on its own, to within its 1e-9.
                let total: f64 = pieces.iter().map(|&(_, f)| f).sum();
                prop_assert!((total - 1.0).abs() < 1e-9, "{total}");
                let mut start = 0.0;
                for &(t, fraction) in &pieces {
                    prop_assert!(fraction >= 0.0);
                    if fraction < 1e-9 {
                        // A hair at a vertex or across a needle may be a neighbour's.
                        start += fraction;
                        continue;
                    }
                    let mid = start + fraction / 2.0;
                    let p = Point::new(a.x + mid * (b.x - a.x), a.y + mid * (b.y - a.y));
                    let [c0, c1, c2] = mesh.triangles[t as usize].map(|v| point(&mesh, v));
                    // Within rounding of the triangle: every edge's signed area ≥ −ε.
                    let scale = 1e-9 * (1.0 + (c1.x - c0.x).abs() + (c2.y - c0.y).abs());
                    for (u, v) in [(c0, c1), (c1, c2), (c2, c0)] {
                        prop_assert!(signed_area_x2(u, v, p) >= -scale, "piece of {t} at {p:?}");
                    }
                    start += fraction;
                }
            }
        }
    }

    #[test]
    fn a_segment_leaving_the_mesh_is_refused() {
        let mesh = sample(700, Criterion::Error);
        let locator = Locator::new(&mesh);
        assert!(!locator.crossings(Point::new(0.5, 0.5), Point::new(3.0, 0.5), |_, _| {}));
        assert!(!locator.crossings(Point::new(3.0, 0.5), Point::new(0.5, 0.5), |_, _| {}));
    }

    #[test]
    fn the_surrogate_is_exact_at_vertices_and_linear_inside_a_triangle() {
        let mesh = sample(2000, Criterion::Error);
        let locator = Locator::new(&mesh);
        for v in mesh.vertices.iter().step_by(7) {
            assert_eq!(locator.value(v.point()), Some(v.z), "at vertex {v:?}");
        }
        let [a, b, c] = mesh.triangles[100].map(|v| mesh.vertices[v as usize]);
        let centroid = Point::new((a.x + b.x + c.x) / 3.0, (a.y + b.y + c.y) / 3.0);
        let got = locator.value(centroid).unwrap();
        assert!((got - (a.z + b.z + c.z) / 3.0).abs() < 1e-12, "{got}");
        assert_eq!(locator.value(Point::new(2.5, 0.5)), None);
        assert_eq!(locator.value(Point::new(f64::NAN, 0.5)), None);
    }

    #[test]
    fn a_sorted_batch_gives_each_point_its_own_value_in_the_given_order() {
        let mesh = sample(3000, Criterion::Error);
        let locator = Locator::new(&mesh);
        let points: Vec<Point> = (0..10_000u32)
            .map(|k| {
                Point::new(
                    -1.2 + 3.4 * (f64::from(k) * 0.618_034).fract(),
                    -0.1 + 1.2 * (f64::from(k) * 0.754_878).fract(),
                )
            })
            .collect();
        let batch = locator.values(&points);
        for (p, got) in points.iter().zip(&batch) {
            match locator.value(*p) {
                Some(v) => assert_eq!(v.to_bits(), got.to_bits(), "at {p:?}"),
                None => assert!(got.is_nan(), "at {p:?}"),
            }
        }
        assert!(batch.iter().any(|v| v.is_nan()) && batch.iter().any(|v| !v.is_nan()));
    }

    #[test]
    fn every_bucket_starts_in_a_triangle_that_holds_its_centre() {
        let mesh = recursive_sample(3000);
        let locator = Locator::new(&mesh);
        for row in 0..locator.rows {
            for col in 0..locator.cols {
                let t = locator.buckets[row * locator.cols + col];
                assert_ne!(t, NONE, "bucket ({col}, {row}) is empty");
                let t = locator.ids[t as usize];
                assert!(contains(
                    mesh.triangles[t as usize].map(|v| point(&mesh, v)),
                    locator.centre(col, row)
                ));
            }
        }
    }
}
