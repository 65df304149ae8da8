//! The nodes of an integer grid that a triangle covers, with their barycentric weights: how
//! grid sources and dense error samples are compared with a mesh.

use super::Point;

/// How far outside the triangle, in barycentric weight, a node still counts as inside, so
/// nodes on an edge are not lost to rounding.
const SLACK: f64 = 1e-9;

/// Calls `visit(i, j, [wa, wb, wc])` for every node (i, j) with i < nx and j < ny in the
/// closed triangle (a, b, c), given in grid units (node (i, j) is the point (i, j)). A node on
/// an edge may be visited for both triangles of that edge; callers that need each node once
/// keep their own record.
pub fn for_each_node(
    [a, b, c]: [Point; 3],
    nx: usize,
    ny: usize,
    mut visit: impl FnMut(usize, usize, [f64; 3]),
) {
    let det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    // The weights of b and c are affine in (x, y): step them along each row instead of
    // solving per node.
    let (wb_dx, wb_dy) = ((c.y - a.y) / det, -(c.x - a.x) / det);
    let (wc_dx, wc_dy) = (-(b.y - a.y) / det, (b.x - a.x) / det);
    // `as usize` saturates, so corners left of or below the grid clamp to 0.
    let lo_i = a.x.min(b.x).min(c.x).ceil().max(0.0) as usize;
    let hi_i = (a.x.max(b.x).max(c.x).floor().max(0.0) as usize).min(nx - 1);
    let lo_j = a.y.min(b.y).min(c.y).ceil().max(0.0) as usize;
    let hi_j = (a.y.max(b.y).max(c.y).floor().max(0.0) as usize).min(ny - 1);
    for j in lo_j..=hi_j {
        let (dx, dy) = (lo_i as f64 - a.x, j as f64 - a.y);
        let mut wb = dx * wb_dx + dy * wb_dy;
        let mut wc = dx * wc_dx + dy * wc_dy;
        for i in lo_i..=hi_i {
            let wa = 1.0 - wb - wc;
            if wa >= -SLACK && wb >= -SLACK && wc >= -SLACK {
                visit(i, j, [wa, wb, wc]);
            }
            wb += wb_dx;
            wc += wc_dx;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_right_triangle_covers_the_nodes_on_and_under_its_hypotenuse() {
        let mut nodes = Vec::new();
        let tri = [Point::new(0.0, 0.0), Point::new(3.0, 0.0), Point::new(0.0, 3.0)];
        for_each_node(tri, 10, 10, |i, j, w| {
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            nodes.push((i, j));
        });
        assert_eq!(nodes.len(), 10, "1 + 2 + 3 + 4 nodes: {nodes:?}");
        assert!(nodes.contains(&(3, 0)) && nodes.contains(&(0, 3)) && nodes.contains(&(1, 2)));
        assert!(!nodes.contains(&(2, 2)));
    }

    #[test]
    fn nodes_outside_the_grid_are_never_visited() {
        let tri = [Point::new(-5.0, -5.0), Point::new(20.0, -5.0), Point::new(-5.0, 20.0)];
        let mut count = 0;
        for_each_node(tri, 4, 3, |i, j, _| {
            assert!(i < 4 && j < 3);
            count += 1;
        });
        assert_eq!(count, 12);
    }
}
