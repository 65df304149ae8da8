//! Triangles that a region's side crosses, cut into pieces that every region holds whole or
//! not at all, so that quadrature never averages a jump of k or f across a piece.
//!
//! Without the cuts, a conductor whose sides no mesh line follows has its current smeared
//! over the triangles it cuts: the energy of a conductor at [0.2, 0.4] × [0.3, 0.7] stalled
//! at 2.5e-3 from the Fourier series' from 10^4 vertices on.

use super::problem::Region;
use crate::geom::Point;

/// The most side lines one triangle is cut along; past it (a coarse triangle under many
/// regions) the remaining lines are averaged by the quadrature rule as before.
const MAX_LINES: usize = 16;

/// A line x = c (`vertical`) or y = c.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Line {
    vertical: bool,
    c: f64,
}

impl Line {
    fn coordinate(&self, p: Point) -> f64 {
        if self.vertical { p.x } else { p.y }
    }
}

/// Calls `piece` with each piece of triangle `p` and the piece's share of its area: the
/// triangle itself with share 1 when no region side crosses its interior, else the fan
/// triangles of the convex pieces the side lines cut it into.
pub(crate) fn try_for_each_piece<E>(
    p: [Point; 3],
    regions: &[Region],
    mut piece: impl FnMut([Point; 3], Option<f64>) -> Result<(), E>,
) -> Result<(), E> {
    let (lo_x, hi_x) = (p[0].x.min(p[1].x).min(p[2].x), p[0].x.max(p[1].x).max(p[2].x));
    let (lo_y, hi_y) = (p[0].y.min(p[1].y).min(p[2].y), p[0].y.max(p[1].y).max(p[2].y));
    let mut lines = [Line { vertical: true, c: 0.0 }; MAX_LINES];
    let mut count = 0;
    // Polygons are not cut: the meshes that carry them follow their sides.
    for rect in regions.iter().filter_map(|r| r.shape.rect()) {
        let (x0, x1, y0, y1) = (rect.x0(), rect.x1(), rect.y0(), rect.y1());
        // A side matters where it crosses the triangle's box strictly and spans part of it.
        let sides = [
            (true, x0, y0 < hi_y && lo_y < y1),
            (true, x1, y0 < hi_y && lo_y < y1),
            (false, y0, x0 < hi_x && lo_x < x1),
            (false, y1, x0 < hi_x && lo_x < x1),
        ];
        for (vertical, c, spans) in sides {
            let (lo, hi) = if vertical { (lo_x, hi_x) } else { (lo_y, hi_y) };
            let line = Line { vertical, c };
            if spans && lo < c && c < hi && count < MAX_LINES && !lines[..count].contains(&line) {
                lines[count] = line;
                count += 1;
            }
        }
    }
    if count == 0 {
        return piece(p, None);
    }
    let area = twice_area(p[0], p[1], p[2]);
    let mut polygons = vec![p.to_vec()];
    for line in &lines[..count] {
        polygons = polygons.into_iter().flat_map(|polygon| split(&polygon, line)).collect();
    }
    for polygon in &polygons {
        for i in 1..polygon.len() - 1 {
            let t = [polygon[0], polygon[i], polygon[i + 1]];
            let a = twice_area(t[0], t[1], t[2]);
            if a > 0.0 {
                piece(t, Some(a / area))?;
            }
        }
    }
    Ok(())
}

/// Twice the signed area of (a, b, c); pieces only weigh the rule, so plain arithmetic does.
fn twice_area(a: Point, b: Point, c: Point) -> f64 {
    (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y)
}

/// The parts of convex `polygon` on either side of `line` (those with three corners or more).
fn split(polygon: &[Point], line: &Line) -> Vec<Vec<Point>> {
    let (mut below, mut above) =
        (Vec::with_capacity(polygon.len() + 1), Vec::with_capacity(polygon.len() + 1));
    for (i, &a) in polygon.iter().enumerate() {
        let b = polygon[(i + 1) % polygon.len()];
        let (sa, sb) = (line.coordinate(a) - line.c, line.coordinate(b) - line.c);
        if sa <= 0.0 {
            below.push(a);
        }
        if sa >= 0.0 {
            above.push(a);
        }
        if (sa < 0.0 && sb > 0.0) || (sa > 0.0 && sb < 0.0) {
            let s = sa / (sa - sb);
            let mut q = Point::new(a.x + s * (b.x - a.x), a.y + s * (b.y - a.y));
            // On the line exactly, so each side's quadrature points stay on its side.
            if line.vertical {
                q.x = line.c
            } else {
                q.y = line.c
            }
            below.push(q);
            above.push(q);
        }
    }
    [below, above].into_iter().filter(|p| p.len() >= 3).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Rect;
    use proptest::prelude::*;

    fn region(x0: f64, x1: f64, y0: f64, y1: f64) -> Region {
        Region::rect(Rect::new(x0, x1, y0, y1).unwrap(), Some(2.0), None)
    }

    fn pieces(p: [Point; 3], regions: &[Region]) -> Vec<([Point; 3], Option<f64>)> {
        let mut out = Vec::new();
        try_for_each_piece::<()>(p, regions, |t, share| {
            out.push((t, share));
            Ok(())
        })
        .unwrap();
        out
    }

    #[test]
    fn a_triangle_no_side_crosses_is_its_own_piece() {
        let t = [Point::new(0.0, 0.0), Point::new(1.0, 0.0), Point::new(0.0, 1.0)];
        // A side along the triangle's edge, and a region far away.
        let p = pieces(t, &[region(0.0, 2.0, -1.0, 0.0), region(5.0, 6.0, 5.0, 6.0)]);
        assert_eq!(p, vec![(t, None)]);
    }

    proptest! {
        #[test]
        fn pieces_tile_the_triangle_and_lie_on_one_side_of_every_region(
            c in proptest::array::uniform3((0.0f64..1.0, 0.0f64..1.0)),
            r in proptest::collection::vec((0.0f64..0.5, 0.0f64..0.5, 0.01f64..0.5, 0.01f64..0.5), 1..4),
        ) {
            let t = c.map(|(x, y)| Point::new(x, y));
            prop_assume!(twice_area(t[0], t[1], t[2]) > 1e-3);
            let regions: Vec<Region> = r.iter().map(|&(x, y, w, h)| region(x, x + w, y, y + h)).collect();
            let pieces = pieces(t, &regions);
            let total: f64 = pieces.iter().map(|(_, s)| s.unwrap_or(1.0)).sum();
            prop_assert!((total - 1.0).abs() < 1e-9, "shares sum to {}", total);
            for (piece, _) in &pieces {
                let centre = Point::new(
                    (piece[0].x + piece[1].x + piece[2].x) / 3.0,
                    (piece[0].y + piece[1].y + piece[2].y) / 3.0,
                );
                for region in &regions {
                    // Every corner is on the same side (inside or outside) as the centre.
                    let inside = region.contains(centre);
                    for q in piece {
                        let eps = 1e-12;
                        let r = region.shape.rect().unwrap();
                        let strictly_out = q.x < r.x0() - eps || q.x > r.x1() + eps || q.y < r.y0() - eps || q.y > r.y1() + eps;
                        let strictly_in = q.x > r.x0() + eps && q.x < r.x1() - eps && q.y > r.y0() + eps && q.y < r.y1() - eps;
                        let straddles = if inside { strictly_out } else { strictly_in };
                        prop_assert!(!straddles, "{piece:?} straddles {region:?}");
                    }
                }
            }
        }
    }
}
