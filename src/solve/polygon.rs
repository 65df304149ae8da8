//! Simple polygons, checked where they are made: enough corners, each finite and inside the
//! domain, no repeated corner, no side that folds back or crosses another, some area.

use crate::geom::predicates::{Orientation, orientation};
use crate::geom::{Point, Rect};

/// The most corners a polygon may have: simplicity is checked pair by pair.
pub const MAX_POLYGON_POINTS: usize = 1000;

/// Why corners do not make a simple polygon inside the domain; `corner` is the index of the
/// corner at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PolygonError {
    /// Fewer than three corners.
    #[error("needs at least 3 points, got {0}")]
    TooFew(usize),
    /// More than [`MAX_POLYGON_POINTS`] corners.
    #[error("has {0} points, more than {MAX_POLYGON_POINTS}")]
    TooMany(usize),
    /// A corner is not finite or lies outside the domain.
    #[error("[{x}, {y}] must be a finite point inside the domain")]
    Outside {
        /// Its index.
        corner: usize,
        /// Its abscissa.
        x: f64,
        /// Its ordinate.
        y: f64,
    },
    /// A corner equals the one before it.
    #[error("repeats the corner before it")]
    Repeated {
        /// Its index.
        corner: usize,
    },
    /// A corner turns back along the side before it.
    #[error("folds back onto the side before it")]
    FoldsBack {
        /// Its index.
        corner: usize,
    },
    /// The side from this corner on crosses or touches an earlier one.
    #[error("its side crosses or touches another: the polygon must be simple")]
    NotSimple {
        /// Its index.
        corner: usize,
    },
    /// The corners enclose no area.
    #[error("encloses no area")]
    NoArea,
}

impl PolygonError {
    /// The corner at fault: none for too few or too many corners, the first for a polygon
    /// that encloses nothing (it is at fault as a whole).
    pub fn corner(&self) -> Option<usize> {
        match *self {
            Self::Outside { corner, .. }
            | Self::Repeated { corner }
            | Self::FoldsBack { corner }
            | Self::NotSimple { corner } => Some(corner),
            Self::NoArea => Some(0),
            Self::TooFew(_) | Self::TooMany(_) => None,
        }
    }
}

/// A simple polygon's corners, in either orientation, without repeating the first, and the
/// box around them, which spares most points the walk around the sides.
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    pub(super) corners: Vec<Point>,
    /// The smallest x and y of the corners.
    pub(super) lo: Point,
    /// The largest.
    pub(super) hi: Point,
}

impl Polygon {
    /// The simple polygon of `corners`, each inside `domain`; -0.0 is taken as 0.0.
    ///
    /// # Errors
    /// The first fault, in this order: too few or too many corners, a corner not finite or
    /// outside `domain` (the first such), then the first corner at which the corners stop
    /// making a simple polygon (decided by exact orientation tests), then no area.
    pub fn try_new(corners: Vec<Point>, domain: Rect) -> Result<Self, PolygonError> {
        if corners.len() < 3 {
            return Err(PolygonError::TooFew(corners.len()));
        }
        if corners.len() > MAX_POLYGON_POINTS {
            return Err(PolygonError::TooMany(corners.len()));
        }
        let corners: Vec<Point> = corners.into_iter().map(|p| Point::new(p.x + 0.0, p.y + 0.0)).collect();
        // NaN and infinite corners fall outside a finite domain too.
        if let Some((corner, p)) = corners.iter().enumerate().find(|(_, p)| !domain.contains(**p)) {
            return Err(PolygonError::Outside { corner, x: p.x, y: p.y });
        }
        let polygon = Self::new(corners);
        match fault(&polygon) {
            Some(e) => Err(e),
            None => Ok(polygon),
        }
    }

    /// The polygon of `corners`, unchecked: [`Polygon::try_new`] is the way in.
    fn new(corners: Vec<Point>) -> Self {
        let fold = |f: fn(f64, f64) -> f64, start: f64| {
            let x = corners.iter().map(|p| p.x).fold(start, f);
            let y = corners.iter().map(|p| p.y).fold(start, f);
            Point::new(x, y)
        };
        let (lo, hi) = (fold(f64::min, f64::INFINITY), fold(f64::max, f64::NEG_INFINITY));
        Self { corners, lo, hi }
    }

    /// The corners.
    pub fn corners(&self) -> &[Point] {
        &self.corners
    }

    /// The area enclosed (the shoelace formula), whatever the orientation.
    pub fn area(&self) -> f64 {
        let n = self.corners.len();
        let twice: f64 = (0..n)
            .map(|i| (self.corners[i], self.corners[(i + 1) % n]))
            .map(|(a, b)| a.x * b.y - b.x * a.y)
            .sum();
        0.5 * twice.abs()
    }
}

/// The `segments − 1` points that divide the circular arc from `from` to `to` into
/// `segments` equal parts, in order: the arc sweeps `degrees` about its centre,
/// counter-clockwise when positive. libm's trigonometry gives the same bits on every machine.
pub fn arc_points(from: Point, to: Point, degrees: f64, segments: usize) -> impl Iterator<Item = Point> {
    let sweep = degrees.to_radians();
    let (dx, dy) = (to.x - from.x, to.y - from.y);
    let chord = libm::hypot(dx, dy);
    let half = 0.5 * sweep.abs();
    let radius = 0.5 * chord / libm::sin(half);
    // The centre lies off the chord's midpoint, to its left for a counter-clockwise sweep
    // (right for clockwise); over half a turn cos(half) < 0 moves it to the other side, where
    // the long way round bulges.
    let off = radius * libm::cos(half) * sweep.signum() / chord;
    let centre = Point::new(0.5 * (from.x + to.x) - off * dy, 0.5 * (from.y + to.y) + off * dx);
    let start = libm::atan2(from.y - centre.y, from.x - centre.x);
    (1..segments).map(move |i| {
        let phi = start + sweep * i as f64 / segments as f64;
        Point::new(centre.x + radius * libm::cos(phi), centre.y + radius * libm::sin(phi))
    })
}

/// The first corner at which `corners` stop making a simple polygon, and why: a repeated
/// corner, a zero-length or backtracking side, or two sides that cross or touch. Decided by
/// exact orientation tests.
fn fault(polygon: &Polygon) -> Option<PolygonError> {
    let corners = polygon.corners();
    let n = corners.len();
    let side = |k: usize| (corners[k], corners[(k + 1) % n]);
    // Whether c lies on the closed segment a–b, given that the three are collinear.
    let within = |a: Point, b: Point, c: Point| {
        a.x.min(b.x) <= c.x && c.x <= a.x.max(b.x) && a.y.min(b.y) <= c.y && c.y <= a.y.max(b.y)
    };
    let touch = |(a, b): (Point, Point), (c, d): (Point, Point)| {
        let (o1, o2) = (orientation(a, b, c), orientation(a, b, d));
        let (o3, o4) = (orientation(c, d, a), orientation(c, d, b));
        let proper = o1 != o2 && o3 != o4 && ![o1, o2, o3, o4].contains(&Orientation::Collinear);
        proper
            || (o1 == Orientation::Collinear && within(a, b, c))
            || (o2 == Orientation::Collinear && within(a, b, d))
            || (o3 == Orientation::Collinear && within(c, d, a))
            || (o4 == Orientation::Collinear && within(c, d, b))
    };
    for k in 0..n {
        let (a, b) = side(k);
        if a == b {
            return Some(PolygonError::Repeated { corner: (k + 1) % n });
        }
        // Two consecutive sides meet only at their shared corner: no fold back along a line.
        let c = corners[(k + 2) % n];
        if orientation(a, b, c) == Orientation::Collinear && within(a, b, c) && c != b {
            return Some(PolygonError::FoldsBack { corner: (k + 2) % n });
        }
        for j in k + 2..n {
            if k == 0 && j == n - 1 {
                continue;
            }
            if touch(side(k), side(j)) {
                return Some(PolygonError::NotSimple { corner: j });
            }
        }
    }
    (polygon.area() == 0.0).then_some(PolygonError::NoArea)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{Region, Shape};

    fn corners(points: &[[f64; 2]]) -> Vec<Point> {
        points.iter().map(|&[x, y]| Point::new(x, y)).collect()
    }

    #[test]
    fn each_fault_names_its_corner_in_the_order_a_reader_finds_them() {
        let unit = Rect::unit();
        let try_new = |points: &[[f64; 2]]| Polygon::try_new(corners(points), unit);
        assert_eq!(try_new(&[[0.1, 0.1], [0.2, 0.1]]), Err(PolygonError::TooFew(2)));
        // A corner outside the domain is named before the bow tie it also makes.
        let outside = try_new(&[[0.1, 0.1], [2.0, 0.9], [0.9, 0.1], [0.1, 0.9]]);
        assert_eq!(outside, Err(PolygonError::Outside { corner: 1, x: 2.0, y: 0.9 }));
        let nan = try_new(&[[0.1, 0.1], [0.9, 0.1], [f64::NAN, 0.9]]).unwrap_err();
        assert_eq!(nan.corner(), Some(2));
        let bow_tie = try_new(&[[0.1, 0.1], [0.9, 0.9], [0.9, 0.1], [0.1, 0.9]]);
        assert_eq!(bow_tie, Err(PolygonError::NotSimple { corner: 2 }));
        let repeated = try_new(&[[0.1, 0.1], [0.1, 0.1], [0.9, 0.1], [0.1, 0.9]]);
        assert_eq!(repeated, Err(PolygonError::Repeated { corner: 1 }));
        let triangle = try_new(&[[0.1, 0.1], [0.9, 0.1], [0.1, 0.9]]).unwrap();
        assert!((triangle.area() - 0.32).abs() < 1e-15, "{}", triangle.area());
    }

    #[test]
    fn arc_points_lie_on_the_circle_in_order_on_the_side_the_sweep_names() {
        let (from, to) = (Point::new(1.0, 0.0), Point::new(0.0, 1.0));
        let on_circle = |c: Point, r: f64| move |p: Point| (p.distance_sq(c).sqrt() - r).abs() < 1e-15;
        // A quarter turn counter-clockwise about the origin.
        let quarter: Vec<_> = arc_points(from, to, 90.0, 3).collect();
        assert_eq!(quarter.len(), 2);
        assert!(quarter.iter().copied().all(on_circle(Point::new(0.0, 0.0), 1.0)), "{quarter:?}");
        let third = Point::new(libm::cos(30f64.to_radians()), 0.5);
        assert!(quarter[0].distance_sq(third) < 1e-30, "{quarter:?}");
        // Three quarters counter-clockwise: the same ends, the centre at (1, 1).
        let long: Vec<_> = arc_points(from, to, 270.0, 3).collect();
        assert!(long.iter().copied().all(on_circle(Point::new(1.0, 1.0), 1.0)), "{long:?}");
        assert!(long[0].distance_sq(Point::new(2.0, 1.0)) < 1e-30, "{long:?}");
        assert!(long[1].distance_sq(Point::new(1.0, 2.0)) < 1e-30, "{long:?}");
        // Three quarters clockwise: about the origin again, the long way round.
        let back: Vec<_> = arc_points(from, to, -270.0, 3).collect();
        assert!(back[0].distance_sq(Point::new(0.0, -1.0)) < 1e-30, "{back:?}");
        assert!(back[1].distance_sq(Point::new(-1.0, 0.0)) < 1e-30, "{back:?}");
        // A quarter turn clockwise: the centre at (1, 1), through the point nearest it.
        let short: Vec<_> = arc_points(from, to, -90.0, 2).collect();
        let mid = Point::new(1.0 - libm::cos(45f64.to_radians()), 1.0 - libm::sin(45f64.to_radians()));
        assert!(short[0].distance_sq(mid) < 1e-30, "{short:?}");
        // Half a turn: the centre is the chord's midpoint.
        let half: Vec<_> = arc_points(Point::new(-1.0, 0.0), Point::new(1.0, 0.0), 180.0, 2).collect();
        assert!(
            half[0].distance_sq(Point::new(0.0, -1.0)) < 1e-30,
            "counter-clockwise from (−1, 0) passes below: {half:?}"
        );
        assert_eq!(arc_points(from, to, 45.0, 1).count(), 0, "one segment is the chord");
    }

    #[test]
    fn a_region_must_lie_inside_the_domain_boundary_included() {
        let domain = Rect::new(0.0, 2.0, 0.0, 1.0).unwrap();
        let on_the_boundary = Shape::Rect(Rect::new(1.0, 2.0, 0.0, 1.0).unwrap());
        assert!(Region::try_new(on_the_boundary, domain).is_ok());
        let across = Shape::Rect(Rect::new(1.5, 2.5, 0.0, 1.0).unwrap());
        assert!(Region::try_new(across, domain).is_err());
    }
}
