//! Exact orientation and in-circle tests: the only place that calls `robust`.
//!
//! `robust` implements Shewchuk's adaptive-precision predicates ("Adaptive Precision
//! Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997): the sign of each
//! result is exact for any finite input, so topology decisions never depend on rounding.

use super::Point;
use robust::Coord;

/// The turn a → b → c makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Orientation {
    /// c lies strictly left of the directed line a → b.
    CounterClockwise,
    /// c lies strictly right of the directed line a → b.
    Clockwise,
    /// a, b and c are exactly collinear.
    Collinear,
}

fn coord(p: Point) -> Coord<f64> {
    Coord { x: p.x, y: p.y }
}

/// The exact orientation of the triangle (a, b, c).
pub fn orientation(a: Point, b: Point, c: Point) -> Orientation {
    let det = robust::orient2d(coord(a), coord(b), coord(c));
    if det > 0.0 {
        Orientation::CounterClockwise
    } else if det < 0.0 {
        Orientation::Clockwise
    } else {
        Orientation::Collinear
    }
}

/// Twice the signed area of (a, b, c): positive when counter-clockwise.
///
/// The sign is exact, as in [`orientation`]; the magnitude is a close approximation, good for
/// comparing against a size floor, not for deciding topology on its own.
pub fn signed_area_x2(a: Point, b: Point, c: Point) -> f64 {
    robust::orient2d(coord(a), coord(b), coord(c))
}

/// Whether (a, b, c) is strictly counter-clockwise, i.e. has positive area.
pub fn is_ccw(a: Point, b: Point, c: Point) -> bool {
    orientation(a, b, c) == Orientation::CounterClockwise
}

/// Whether `d` lies strictly inside the circle through the counter-clockwise triangle (a, b, c).
///
/// Points exactly on the circle are *not* inside: the semi-recursive algorithm flips only on a
/// strict violation, so the many cocircular quadrilaterals of dyadic meshes stay as they are and
/// flipping terminates deterministically.
pub fn is_in_circle(a: Point, b: Point, c: Point, d: Point) -> bool {
    debug_assert!(is_ccw(a, b, c), "in-circle test on a triangle that is not CCW");
    robust::incircle(coord(a), coord(b), coord(c), coord(d)) > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_follows_the_counter_clockwise_convention() {
        let (a, b) = (Point::new(0.0, 0.0), Point::new(1.0, 0.0));
        assert_eq!(orientation(a, b, Point::new(0.5, 1.0)), Orientation::CounterClockwise);
        assert_eq!(orientation(a, b, Point::new(0.5, -1.0)), Orientation::Clockwise);
        assert_eq!(orientation(a, b, Point::new(7.0, 0.0)), Orientation::Collinear);
    }

    #[test]
    fn orientation_is_exact_where_floating_point_is_not() {
        // Nearly collinear points on which the naive determinant gets the sign wrong or zero.
        let a = Point::new(0.5, 0.5);
        let b = Point::new(12.0, 12.0);
        let c = Point::new(24.0, 24.0);
        assert_eq!(orientation(a, b, c), Orientation::Collinear);
        let c = Point::new(24.0, 24.0 + f64::EPSILON * 16.0);
        assert_eq!(orientation(a, b, c), Orientation::CounterClockwise);
    }

    #[test]
    fn cocircular_points_are_not_in_circle() {
        // The four corners of a square are cocircular.
        let (a, b, c) = (Point::new(0.0, 0.0), Point::new(1.0, 0.0), Point::new(1.0, 1.0));
        assert!(!is_in_circle(a, b, c, Point::new(0.0, 1.0)));
        assert!(is_in_circle(a, b, c, Point::new(0.1, 0.9)));
        assert!(!is_in_circle(a, b, c, Point::new(-0.1, 1.0)));
    }
}
