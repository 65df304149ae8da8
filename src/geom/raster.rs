//! The nodes of an integer grid that a triangle covers, row by row, and the triangle's plane:
//! how grid sources and dense error samples are compared with a mesh.
//!
//! Rows rather than nodes, so that callers run a tight loop over a contiguous slice of grid
//! values with the interpolant stepping along it.

use super::Point;

/// How far outside the triangle, in grid units, a node still counts as inside, so nodes on an
/// edge are not lost to rounding (which is below 1e-12 here for grids up to 2^20 nodes wide).
const SLACK: f64 = 1e-9;

/// Calls `visit(j, i0, i1)` for every row j < ny that has nodes in the closed triangle
/// (a, b, c), given in grid units (node (i, j) is the point (i, j)): nodes i0..=i1 of row j,
/// clipped to i < nx. A node on an edge may be visited for both triangles of that edge;
/// callers that need each node once keep their own record.
pub fn for_each_span(
    [a, b, c]: [Point; 3],
    nx: usize,
    ny: usize,
    mut visit: impl FnMut(usize, usize, usize),
) {
    // Each edge as its lower end, upper end's y and dx/dy; horizontal edges add nothing the
    // other two do not.
    let edges = [(a, b), (b, c), (c, a)].map(|(p, q)| {
        let (lo, hi) = if p.y <= q.y { (p, q) } else { (q, p) };
        (lo, hi.y, (hi.x - lo.x) / (hi.y - lo.y))
    });
    // `as usize` saturates, so corners below the grid clamp to 0.
    let lo_j = a.y.min(b.y).min(c.y).ceil().max(0.0) as usize;
    let hi_j = (a.y.max(b.y).max(c.y).floor().max(0.0) as usize).min(ny - 1);
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
            // Both are in [0, nx − 1] now, where `as` truncation is floor, and cheaper than
            // a call to ceil or floor (SSE2 has no rounding instruction).
            let (first, last) = (left as usize, right as usize);
            let first = if (first as f64) < left { first + 1 } else { first };
            if first <= last {
                visit(j, first, last);
            }
        }
    }
}

/// The linear interpolant of a triangle's corner values, as a function of grid position.
#[derive(Debug, Clone, Copy)]
pub struct Plane {
    origin: Point,
    z: f64,
    dz_dx: f64,
    dz_dy: f64,
}

impl Plane {
    /// The plane through (a, za), (b, zb), (c, zc); the triangle must not be degenerate.
    pub fn new([a, b, c]: [Point; 3], [za, zb, zc]: [f64; 3]) -> Self {
        let (bx, by, cx, cy) = (b.x - a.x, b.y - a.y, c.x - a.x, c.y - a.y);
        let det = bx * cy - by * cx;
        let (dzb, dzc) = (zb - za, zc - za);
        Self { origin: a, z: za, dz_dx: (dzb * cy - dzc * by) / det, dz_dy: (dzc * bx - dzb * cx) / det }
    }

    /// The values at nodes i0, i0 + 1, … of row j, stepped rather than solved per node.
    #[inline]
    pub fn row(&self, i0: usize, j: usize) -> impl Iterator<Item = f64> + use<> {
        let start =
            self.z + (j as f64 - self.origin.y) * self.dz_dy + (i0 as f64 - self.origin.x) * self.dz_dx;
        let step = self.dz_dx;
        // An i32 count converts to f64 in one instruction; usize (u64) takes several.
        (0..).map(move |k: i32| start + f64::from(k) * step)
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
        let plane = Plane::new(tri, [1.0, -2.0, 4.0]);
        let at = |x: usize, y: usize| plane.row(x, y).next().unwrap();
        assert!((at(1, 1) - 1.0).abs() < 1e-12 && (at(5, 2) + 2.0).abs() < 1e-12);
        assert!((at(2, 6) - 4.0).abs() < 1e-12);
        let row: Vec<f64> = plane.row(2, 3).take(3).collect();
        assert!((row[0] - at(2, 3)).abs() < 1e-12 && (row[2] - at(4, 3)).abs() < 1e-12);
    }

    proptest! {
        /// The spans are exactly the nodes whose barycentric weights are all ≥ 0, up to nodes
        /// within rounding of an edge.
        #[test]
        fn spans_hold_the_nodes_inside_the_triangle(
            corners in proptest::array::uniform3((-3.0f64..40.0, -3.0f64..40.0)),
        ) {
            let [a, b, c] = corners.map(|(x, y)| Point::new(x, y));
            let det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
            prop_assume!(det.abs() > 1.0);
            let (nx, ny) = (33, 29);
            let spans = nodes([a, b, c], nx, ny);
            for j in 0..ny {
                for i in 0..nx {
                    let p = Point::new(i as f64, j as f64);
                    let edge = |p0: Point, p1: Point| {
                        ((p1.x - p0.x) * (p.y - p0.y) - (p1.y - p0.y) * (p.x - p0.x)) / det
                    };
                    let w = [edge(b, c), edge(c, a), edge(a, b)];
                    let inside = w.iter().all(|&w| w >= 1e-9);
                    let outside = w.iter().any(|&w| w <= -1e-6);
                    let listed = spans.contains(&(i, j));
                    prop_assert!(!inside || listed, "({i}, {j}) inside but not visited");
                    prop_assert!(!outside || !listed, "({i}, {j}) outside but visited");
                }
            }
        }
    }
}
