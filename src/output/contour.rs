//! Contour lines of a function that is linear on each triangle: the field lines a picture of a
//! magnetostatic solution draws (B = (∂A/∂y, −∂A/∂x) is tangent to the contours of A, and
//! equally spaced contours crowd where |B| is large).
//!
//! Each triangle gives at most one straight piece per level. A piece's ends lie on the
//! triangle's edges, computed from the edge's lower vertex id to its higher, so the two
//! triangles that share an edge put the line through the same point, bit for bit.

/// `count` values spread evenly over [lo, hi], each the middle of one of `count` equal bands:
/// none at an end, where a Dirichlet side holds A = 0 along its whole length.
pub(crate) fn levels(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    let span = hi - lo;
    if !(span > 0.0 && span.is_finite()) {
        return Vec::new();
    }
    let step = span / count as f64;
    (0..count).map(|k| lo + (k as f64 + 0.5) * step).collect()
}

/// A triangle's corners: vertex id, and x, y, z.
pub(crate) type Corner = (u32, [f64; 3]);

/// Calls `piece(p, q)` with the ends (x, y) of each contour at `levels` (ascending) that
/// crosses the triangle with `corners`, lowest level first. A corner is above a level when its
/// z is at least the level, and a piece joins the two edges whose ends are on different sides.
pub(crate) fn pieces(corners: [Corner; 3], levels: &[f64], mut piece: impl FnMut([f64; 2], [f64; 2])) {
    let z = corners.map(|(_, [_, _, z])| z);
    let (lo, hi) = (z[0].min(z[1]).min(z[2]), z[0].max(z[1]).max(z[2]));
    // Levels in (lo, hi] have a corner on each side; the others miss the triangle.
    let first = levels.partition_point(|&l| l <= lo);
    let end = levels.partition_point(|&l| l <= hi);
    for &level in &levels[first..end] {
        let mut ends = [[0.0; 2]; 2];
        let mut found = 0;
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            if (z[i] >= level) != (z[j] >= level) {
                ends[found] = crossing(corners[i], corners[j], level);
                found += 1;
            }
        }
        debug_assert_eq!(found, 2, "a level strictly inside a triangle's range crosses two edges");
        // A level equal to the top corner's z meets the triangle at that corner alone.
        if ends[0] != ends[1] {
            piece(ends[0], ends[1]);
        }
    }
}

/// Where the edge between `a` and `b` (z on either side of `level`) reaches `level`.
fn crossing(a: Corner, b: Corner, level: f64) -> [f64; 2] {
    let ((_, [x0, y0, z0]), (_, [x1, y1, z1])) = if a.0 < b.0 { (a, b) } else { (b, a) };
    let t = (level - z0) / (z1 - z0);
    [x0 + t * (x1 - x0), y0 + t * (y1 - y0)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::sample;

    #[test]
    fn levels_are_the_middles_of_equal_bands() {
        assert_eq!(levels(0.0, 4.0, 4), [0.5, 1.5, 2.5, 3.5]);
        assert_eq!(levels(-1.0, 1.0, 2), [-0.5, 0.5]);
        assert!(levels(1.0, 1.0, 20).is_empty() && levels(0.0, f64::INFINITY, 20).is_empty());
    }

    #[test]
    fn a_level_through_a_corner_or_along_an_edge_gives_the_right_piece() {
        let corners = |z: [f64; 3]| [(0, [0.0, 0.0, z[0]]), (1, [1.0, 0.0, z[1]]), (2, [0.0, 1.0, z[2]])];
        let collect = |z, levels: &[f64]| {
            let mut out = Vec::new();
            pieces(corners(z), levels, |p, q| out.push((p, q)));
            out
        };
        // Through the middle of two edges.
        assert_eq!(collect([0.0, 2.0, 2.0], &[1.0]), [([0.5, 0.0], [0.0, 0.5])]);
        // Only touching the top corner: nothing; touching the bottom corner: nothing either.
        assert!(collect([0.0, 0.0, 1.0], &[1.0]).is_empty());
        assert!(collect([0.0, 1.0, 1.0], &[0.0]).is_empty());
        // Along the edge whose ends are both at the level.
        assert_eq!(collect([1.0, 1.0, 0.0], &[1.0]), [([1.0, 0.0], [0.0, 0.0])]);
        // Levels outside the range miss; several inside give one piece each, lowest first.
        let many = collect([0.0, 4.0, 2.0], &[-1.0, 1.0, 3.0, 5.0]);
        assert_eq!(many.len(), 2);
        assert_eq!(many[0].0, [0.25, 0.0]);
    }

    /// Length of the line a x + b y = level inside [x0, x1] × [y0, y1] (a, b > 0).
    fn line_length(a: f64, b: f64, level: f64, [x0, x1, y0, y1]: [f64; 4]) -> f64 {
        // The ends: where the line enters and leaves the rectangle, by clipping its x range.
        let x_at = |y: f64| (level - b * y) / a;
        let (from, to) = (x_at(y1).max(x0), x_at(y0).min(x1));
        if from >= to { 0.0 } else { (to - from) * (1.0 + (a / b).powi(2)).sqrt() }
    }

    #[test]
    fn over_a_mesh_a_linear_functions_contours_are_its_straight_lines_whole_and_drawn_once() {
        // The interpolant of a linear function is the function itself, so the pieces of each
        // level lie on its line and add up to the line's length in the domain: a gap, or an
        // edge crossed from both sides, would change the sum.
        let mut result = sample(800, Criterion::Error);
        let (a, b) = (2.0, 3.0);
        result.vertices.iter_mut().for_each(|v| v.z = a * v.x + b * v.y);
        let (lo, hi) = result.z_range();
        let levels = levels(lo, hi, 7);
        let mut lengths = vec![0.0; levels.len()];
        for tri in &result.triangles {
            let corners = tri.map(|v| {
                let p = result.vertices[v as usize];
                (v, [p.x, p.y, p.z])
            });
            pieces(corners, &levels, |p, q| {
                let level = a * p[0] + b * p[1];
                let k = levels.iter().position(|&l| (l - level).abs() < 1e-9).expect("on a level");
                assert!((a * q[0] + b * q[1] - levels[k]).abs() < 1e-9, "{p:?} {q:?}");
                lengths[k] += ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
            });
        }
        for (k, &level) in levels.iter().enumerate() {
            let exact = line_length(a, b, level, result.bounds());
            assert!(
                (lengths[k] - exact).abs() < 1e-9 * exact,
                "level {level}: {} against {exact}",
                lengths[k]
            );
        }
    }
}
