//! The nodes of an integer grid that a triangle covers, row by row, and the triangle's plane:
//! how grid sources and dense error samples are compared with a mesh.
//!
//! Rows rather than nodes, so that callers run a tight loop over a contiguous slice of grid
//! values with the interpolant stepping along it.

use super::Point;

/// How far outside the triangle, in grid units, a node still counts as inside, so a node on an
/// edge is not lost to rounding. (Between two triangles nothing is lost anyway: both compute
/// their shared edge's crossings with the same bits, and one of them takes the node.)
const SLACK: f64 = 1e-9;

/// A node index as a coordinate. Through i64, which converts in one instruction where usize
/// (u64) takes several; exact, as every index is below 2^53.
#[inline]
fn coordinate(k: usize) -> f64 {
    k as i64 as f64
}

/// Calls `visit(j, i0, i1)` for every row j < ny that has nodes in the closed triangle
/// (a, b, c), given in grid units (node (i, j) is the point (i, j)): nodes i0..=i1 of row j,
/// clipped to i < nx. A node on an edge may be visited for both triangles of that edge;
/// callers that need each node once keep their own record.
///
/// A row's span runs between the crossings of the edges that reach it: the long edge from the
/// lowest corner to the highest, and the short edge below or above the middle corner (both at
/// its height). Each crossing is the edge's lower end plus a step along it, so the two
/// triangles of an edge find the same bits there.
pub fn for_each_span(
    [a, b, c]: [Point; 3],
    nx: usize,
    ny: usize,
    mut visit: impl FnMut(usize, usize, usize),
) {
    // Corners by height: low, middle, high.
    let (low, middle, high) = {
        let (p, q) = if a.y <= b.y { (a, b) } else { (b, a) };
        if c.y < p.y {
            (c, p, q)
        } else if c.y < q.y {
            (p, c, q)
        } else {
            (p, q, c)
        }
    };
    // `as usize` truncates towards zero and saturates, so for y ≥ 0 it is floor, and corners
    // below the grid clamp to 0 (SSE2 has no rounding instruction, so ceil and floor are
    // calls).
    let lo_j = low.y as usize;
    let lo_j = if (lo_j as f64) < low.y { lo_j.saturating_add(1) } else { lo_j };
    let hi_j = (high.y as usize).min(ny - 1);
    if lo_j > hi_j || high.y < 0.0 {
        // No row crosses the triangle, as often happens once triangles are smaller than a
        // grid cell: skip the divisions. (A triangle wholly below row 0 has hi_j = 0 from
        // the saturating cast, and row 0 would be read off its edges' extensions.)
        return;
    }
    // A triangle flat along a row has no edge that crosses rows.
    let Some(long) = Crossing::new(low, high) else { return };
    // A short edge flat along a row reaches no row but its own, where the long edge and the
    // other short edge bound the span: it adds nothing, and is `None`.
    let (below, above) = (Crossing::new(low, middle), Crossing::new(middle, high));
    let last_i = coordinate(nx - 1);
    for j in lo_j..=hi_j {
        let y = coordinate(j);
        let x = long.at(y);
        let (mut left, mut right) = (x, x);
        let mut cover = |x: f64| {
            left = if x < left { x } else { left };
            right = if x > right { x } else { right };
        };
        if let Some(below) = below
            && y <= middle.y
        {
            cover(below.at(y));
        }
        if let Some(above) = above
            && y >= middle.y
        {
            cover(above.at(y));
        }
        let (left, right) = ((left - SLACK).max(0.0), (right + SLACK).min(last_i));
        if left <= right {
            // Both are in [0, nx − 1] now, where `as` truncation is floor (through i64 for the
            // reason `coordinate` gives).
            let (first, last) = (left as i64, right as i64);
            let (first, last) =
                (if (first as f64) < left { first + 1 } else { first } as usize, last as usize);
            if first <= last {
                visit(j, first, last);
            }
        }
    }
}

/// Where an edge crosses the rows between its ends.
#[derive(Clone, Copy)]
struct Crossing {
    /// The lower end.
    from: Point,
    /// Δx per unit of y.
    dx_dy: f64,
}

impl Crossing {
    /// The edge from `lower` up to `upper`, or `None` when it is flat along a row.
    #[inline]
    fn new(lower: Point, upper: Point) -> Option<Self> {
        (lower.y < upper.y).then(|| Self { from: lower, dx_dy: (upper.x - lower.x) / (upper.y - lower.y) })
    }

    #[inline]
    fn at(self, y: f64) -> f64 {
        self.from.x + (y - self.from.y) * self.dx_dy
    }
}

/// The linear interpolant of a triangle's corner values, as a function of grid position.
#[derive(Debug, Clone, Copy)]
pub struct Plane {
    origin: Point,
    z: f64,
    dz_dx: f64,
    dz_dy: f64,
    /// The corner values' range, which holds every value inside the triangle.
    z_range: (f64, f64),
}

impl Plane {
    /// The plane through (a, za), (b, zb), (c, zc), or `None` when the triangle is flat in
    /// floating point (it covers no area, so its nodes are its neighbours').
    pub fn new([a, b, c]: [Point; 3], [za, zb, zc]: [f64; 3]) -> Option<Self> {
        let (bx, by, cx, cy) = (b.x - a.x, b.y - a.y, c.x - a.x, c.y - a.y);
        let det = bx * cy - by * cx;
        let (dzb, dzc) = (zb - za, zc - za);
        let (dz_dx, dz_dy) = ((dzb * cy - dzc * by) / det, (dzc * bx - dzb * cx) / det);
        (dz_dx.is_finite() && dz_dy.is_finite()).then_some(Self {
            origin: a,
            z: za,
            dz_dx,
            dz_dy,
            z_range: (za.min(zb).min(zc), za.max(zb).max(zc)),
        })
    }

    /// The values at nodes i0, i0 + 1, … of row j, stepped rather than solved per node.
    ///
    /// Clamped to the corner values: a node let in by the slack just outside a sliver, whose
    /// plane is steep, must not read an extrapolated value.
    #[inline]
    pub fn row(&self, i0: usize, j: usize) -> impl Iterator<Item = f64> + use<> {
        let row = self.row_at(i0, j);
        (0..).map(move |k: i32| row.at(k))
    }

    /// Row j from node i0 on, evaluated at any step k (node i0 + k) with the same bits as
    /// [`Plane::row`]'s k-th value.
    #[inline]
    pub fn row_at(&self, i0: usize, j: usize) -> PlaneRow {
        let (x, y) = (coordinate(i0), coordinate(j));
        let start = self.z + (y - self.origin.y) * self.dz_dy + (x - self.origin.x) * self.dz_dx;
        PlaneRow { start, step: self.dz_dx, range: self.z_range }
    }
}

/// A plane along one row of nodes; see [`Plane::row_at`].
#[derive(Debug, Clone, Copy)]
pub struct PlaneRow {
    start: f64,
    step: f64,
    range: (f64, f64),
}

impl PlaneRow {
    /// The value k nodes along. Monotone in k (each operation rounds monotonically), so the
    /// values of a run of nodes lie between those at its ends.
    #[inline]
    pub fn at(&self, k: i32) -> f64 {
        // An i32 count converts to f64 in one instruction; usize (u64) takes several.
        self.at_step(f64::from(k))
    }

    /// [`PlaneRow::at`] for a whole number `k` held as an f64.
    ///
    /// Clamped by comparisons, which compile to one instruction each where `f64::max` and
    /// `f64::min` add NaN handling: a NaN (from an overflowed plane) still becomes the lower
    /// end, and the two can differ only in the sign of a zero, which no |value − F_n| sees.
    #[inline]
    fn at_step(&self, k: f64) -> f64 {
        let (lo, hi) = self.range;
        let z = self.start + k * self.step;
        let z = if z > lo { z } else { lo };
        if z < hi { z } else { hi }
    }

    /// The larger of `floor` and the largest |v − self.at(k0 + k)| over the run, v = `values[k]`.
    ///
    /// The same maximum, to the bit, as one comparison after another: a maximum does not
    /// depend on the order it is taken in. Four running maxima instead of one let the
    /// comparisons overlap (with one, each waits for the one before), and counting k in f64
    /// (exact below 2^53) saves a conversion per node.
    #[inline]
    pub fn max_deviation(&self, k0: i32, values: &[f64], floor: f64) -> f64 {
        const LANES: usize = 4;
        // A plain comparison is the maximum: the deviations of finite values are not NaN.
        let larger = |m: f64, e: f64| if e > m { e } else { m };
        let mut lanes = [floor; LANES];
        let mut k = f64::from(k0);
        let mut runs = values.chunks_exact(LANES);
        for run in &mut runs {
            for (lane, (m, &value)) in lanes.iter_mut().zip(run).enumerate() {
                *m = larger(*m, (value - self.at_step(k + lane as f64)).abs());
            }
            k += LANES as f64;
        }
        let mut max = lanes.into_iter().fold(floor, larger);
        for (lane, &value) in runs.remainder().iter().enumerate() {
            max = larger(max, (value - self.at_step(k + lane as f64)).abs());
        }
        max
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn nodes(tri: [Point; 3], nx: usize, ny: usize) -> Vec<(usize, usize)> {
        let mut nodes = Vec::new();
        for_each_span(tri, nx, ny, |j, i0, i1| nodes.extend((i0..=i1).map(|i| (i, j))));
        nodes
    }

    #[test]
    fn a_right_triangle_covers_the_nodes_on_and_under_its_hypotenuse() {
        let nodes = nodes([Point::new(0.0, 0.0), Point::new(3.0, 0.0), Point::new(0.0, 3.0)], 10, 10);
        assert_eq!(nodes.len(), 10, "1 + 2 + 3 + 4 nodes: {nodes:?}");
        assert!(nodes.contains(&(3, 0)) && nodes.contains(&(0, 3)) && nodes.contains(&(1, 2)));
        assert!(!nodes.contains(&(2, 2)));
    }

    #[test]
    fn nodes_outside_the_grid_are_never_visited() {
        let tri = [Point::new(-5.0, -5.0), Point::new(20.0, -5.0), Point::new(-5.0, 20.0)];
        let nodes = nodes(tri, 4, 3);
        assert!(nodes.iter().all(|&(i, j)| i < 4 && j < 3));
        assert_eq!(nodes.len(), 12);
    }

    #[test]
    fn the_plane_passes_through_the_corners_and_steps_along_rows() {
        let tri = [Point::new(1.0, 1.0), Point::new(5.0, 2.0), Point::new(2.0, 6.0)];
        let plane = Plane::new(tri, [1.0, -2.0, 4.0]).unwrap();
        let at = |x: usize, y: usize| plane.row(x, y).next().unwrap();
        assert!((at(1, 1) - 1.0).abs() < 1e-12 && (at(5, 2) + 2.0).abs() < 1e-12);
        assert!((at(2, 6) - 4.0).abs() < 1e-12);
        let row: Vec<f64> = plane.row(2, 3).take(3).collect();
        assert!((row[0] - at(2, 3)).abs() < 1e-12 && (row[2] - at(4, 3)).abs() < 1e-12);
        // Outside the triangle the plane would leave the corner values; it stays within them.
        assert_eq!(at(30, 1), -2.0);
        let flat = [Point::new(0.0, 0.0), Point::new(1.0, 1.0), Point::new(2.0, 2.0)];
        assert!(Plane::new(flat, [0.0, 1.0, 5.0]).is_none());
    }

    /// The oracle for [`for_each_span`]: its spans as engine 6 found them, every edge tested
    /// at every row.
    fn reference_spans(
        [a, b, c]: [Point; 3],
        nx: usize,
        ny: usize,
        mut visit: impl FnMut(usize, usize, usize),
    ) {
        // `as usize` truncates towards zero and saturates, so for y ≥ 0 it is floor, and corners
        // below the grid clamp to 0 (SSE2 has no rounding instruction, so ceil and floor are
        // calls).
        let (lo_y, hi_y) = (a.y.min(b.y).min(c.y), a.y.max(b.y).max(c.y));
        let lo_j = lo_y as usize;
        let lo_j = if (lo_j as f64) < lo_y { lo_j.saturating_add(1) } else { lo_j };
        let hi_j = (hi_y as usize).min(ny - 1);
        if lo_j > hi_j {
            // No row crosses the triangle, as often happens once triangles are smaller than a
            // grid cell: skip the divisions below.
            return;
        }
        // Each edge as its lower end, upper end's y and dx/dy; horizontal edges add nothing the
        // other two do not.
        let edges = [(a, b), (b, c), (c, a)].map(|(p, q)| {
            let (lo, hi) = if p.y <= q.y { (p, q) } else { (q, p) };
            (lo, hi.y, (hi.x - lo.x) / (hi.y - lo.y))
        });
        let last_i = (nx - 1) as f64;
        for j in lo_j..=hi_j {
            let y = j as f64;
            let (mut left, mut right) = (f64::INFINITY, f64::NEG_INFINITY);
            for &(lo, hi_y, dx_dy) in &edges {
                if lo.y <= y && y <= hi_y && lo.y < hi_y {
                    let x = lo.x + (y - lo.y) * dx_dy;
                    left = left.min(x);
                    right = right.max(x);
                }
            }
            let (left, right) = ((left - SLACK).max(0.0), (right + SLACK).min(last_i));
            if left <= right {
                // Both are in [0, nx − 1] now, where `as` truncation is floor.
                let (first, last) = (left as usize, right as usize);
                let first = if (first as f64) < left { first + 1 } else { first };
                if first <= last {
                    visit(j, first, last);
                }
            }
        }
    }

    /// Signed distance of `p` from the line a→b, positive on its left.
    fn left_of(a: Point, b: Point, p: Point) -> f64 {
        ((b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)) / a.distance_sq(b).sqrt()
    }

    proptest! {
        /// Four running maxima find the maximum one comparison after another finds, and the
        /// plane's values differ from `max`-then-`min` clamping in no |value − F_n|.
        #[test]
        fn max_deviation_is_the_maximum_of_the_run_in_order(
            start in -10.0f64..10.0,
            step in prop_oneof![Just(0.0), -3.0f64..3.0, Just(1e300)],
            range in (-20.0f64..0.0, 0.0f64..20.0),
            k0 in 0i32..100,
            values in proptest::collection::vec(
                prop_oneof![Just(0.0), Just(-0.0), -25.0f64..25.0],
                0..40,
            ),
            floor in prop_oneof![Just(0.0), 0.0f64..30.0],
        ) {
            let row = PlaneRow { start, step, range };
            let clamped = |k: i32| (start + f64::from(k) * step).max(range.0).min(range.1);
            let mut expected = floor;
            for (k, &value) in (k0..).zip(&values) {
                let e = (value - clamped(k)).abs();
                prop_assert_eq!(e.to_bits(), (value - row.at(k)).abs().to_bits(), "node {}", k);
                if e > expected {
                    expected = e;
                }
            }
            prop_assert_eq!(row.max_deviation(k0, &values, floor).to_bits(), expected.to_bits());
        }

        /// The spans are the nodes inside the triangle, up to nodes within rounding of an edge.
        #[test]
        fn spans_hold_the_nodes_inside_the_triangle(
            corners in proptest::array::uniform3((-3.0f64..40.0, -3.0f64..40.0)),
        ) {
            let [a, b, c] = corners.map(|(x, y)| Point::new(x, y));
            prop_assume!(left_of(a, b, c).abs() > 1e-3);
            let (nx, ny) = (33, 29);
            let spans = nodes([a, b, c], nx, ny);
            let sign = left_of(a, b, c).signum();
            for (i, j) in (0..ny).flat_map(|j| (0..nx).map(move |i| (i, j))) {
                let p = Point::new(i as f64, j as f64);
                let d = [left_of(a, b, p), left_of(b, c, p), left_of(c, a, p)].map(|d| d * sign);
                let listed = spans.contains(&(i, j));
                prop_assert!(!d.iter().all(|&d| d >= 1e-12) || listed, "({i}, {j}) inside, not visited");
                prop_assert!(!d.iter().any(|&d| d <= -1e-6) || !listed, "({i}, {j}) outside, visited");
            }
        }

        /// The long-edge-and-short-edge walk visits the spans of every edge at every row, to
        /// the bit: same nodes, so the same maxima and the same meshes.
        #[test]
        fn spans_are_those_of_every_edge_at_every_row(
            corners in proptest::array::uniform3(prop_oneof![
                (-3.0f64..40.0, -3.0f64..40.0),
                (-3i32..40, -3i32..40).prop_map(|(x, y)| (f64::from(x), f64::from(y))),
                (-6i32..80, -6i32..80).prop_map(|(x, y)| (f64::from(x) * 0.5, f64::from(y) * 0.5)),
            ]),
            order in 0usize..6,
        ) {
            let [a, b, c] = corners.map(|(x, y)| Point::new(x, y));
            let tri = [[a, b, c], [a, c, b], [b, a, c], [b, c, a], [c, a, b], [c, b, a]][order];
            let (nx, ny) = (33, 29);
            let mut expected = Vec::new();
            reference_spans(tri, nx, ny, |j, i0, i1| expected.push((j, i0, i1)));
            let mut found = Vec::new();
            for_each_span(tri, nx, ny, |j, i0, i1| found.push((j, i0, i1)));
            prop_assert_eq!(found, expected);
        }

        /// Two triangles that share an edge lose no node on it: with integer corners (edges
        /// through nodes), every node of the closed quadrilateral is visited by one of them.
        #[test]
        fn triangles_sharing_an_edge_lose_no_node(
            corners in proptest::array::uniform4((0i64..24, 0i64..24)),
        ) {
            let [a, mut b, c, mut d] = corners;
            let cross = |p: (i64, i64), q: (i64, i64), r: (i64, i64)| {
                (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0)
            };
            // b and d strictly on opposite sides of the diagonal a–c (reflecting d through its
            // midpoint if need be), b on its right: then a b c and a c d are counter-clockwise.
            prop_assume!(cross(a, c, b) != 0 && cross(a, c, d) != 0);
            if (cross(a, c, b) > 0) == (cross(a, c, d) > 0) {
                d = (a.0 + c.0 - d.0, a.1 + c.1 - d.1);
            }
            if cross(a, c, b) > 0 {
                std::mem::swap(&mut b, &mut d);
            }
            let point = |(x, y): (i64, i64)| Point::new(x as f64, y as f64);
            let mut visited = nodes([a, b, c].map(point), 24, 24);
            visited.extend(nodes([a, c, d].map(point), 24, 24));
            let inside = |[u, v, w]: [(i64, i64); 3], p| cross(u, v, p) >= 0 && cross(v, w, p) >= 0 && cross(w, u, p) >= 0;
            for (i, j) in (0..24i64).flat_map(|j| (0..24i64).map(move |i| (i, j))) {
                if inside([a, b, c], (i, j)) || inside([a, c, d], (i, j)) {
                    prop_assert!(visited.contains(&(i as usize, j as usize)), "({i}, {j}) lost");
                }
            }
        }
    }
}
