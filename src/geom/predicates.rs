//! Exact orientation and in-circle tests: the only place that calls `robust`.
//!
//! `robust` implements Shewchuk's adaptive-precision predicates ("Adaptive Precision
//! Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997): the sign of each
//! result is exact for any finite input, so topology decisions never depend on rounding.
//!
//! The in-circle test takes one shortcut of its own. Meshes of grids and of dyadic midpoints
//! are full of exactly cocircular quadrilaterals (the four nodes of a pixel, the four children
//! of a square), on which the floating-point filter can never decide and `robust` falls to its
//! adaptive stage, which zeroes a few kilobytes of scratch per call: that was 40% of a DEM
//! run's instructions. Such points are small multiples of one power of two, so there the
//! determinant is evaluated exactly in integers instead. The sign is the same exact sign
//! `robust` gives (a proptest holds them together); only the cost differs.

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
    // Shewchuk's first stage, as `robust` runs it: the rounded determinant and a bound on its
    // error. Most calls end here.
    let [adx, ady, bdx, bdy, cdx, cdy] = [a.x - d.x, a.y - d.y, b.x - d.x, b.y - d.y, c.x - d.x, c.y - d.y];
    let (bdxcdy, cdxbdy, cdxady, adxcdy, adxbdy, bdxady) =
        (bdx * cdy, cdx * bdy, cdx * ady, adx * cdy, adx * bdy, bdx * ady);
    let (alift, blift, clift) = (adx * adx + ady * ady, bdx * bdx + bdy * bdy, cdx * cdx + cdy * cdy);
    let det = alift * (bdxcdy - cdxbdy) + blift * (cdxady - adxcdy) + clift * (adxbdy - bdxady);
    let permanent = (bdxcdy.abs() + cdxbdy.abs()) * alift
        + (cdxady.abs() + adxcdy.abs()) * blift
        + (adxbdy.abs() + bdxady.abs()) * clift;
    if det.abs() > INCIRCLE_BOUND * permanent {
        return det > 0.0;
    }
    match on_lattice([a, b, c, d]) {
        Some([a, b, c, d]) => lattice_in_circle(a, b, c, d) > 0,
        None => robust::incircle(coord(a), coord(b), coord(c), coord(d)) > 0.0,
    }
}

/// Shewchuk's `iccerrboundA`, (10 + 96ε)ε with ε = 2⁻⁵³: when the rounded in-circle
/// determinant exceeds this times its permanent, its sign is right.
const INCIRCLE_BOUND: f64 = (10.0 + 96.0 * HALF_EPSILON) * HALF_EPSILON;
const HALF_EPSILON: f64 = f64::EPSILON / 2.0;

/// How many bits a lattice coordinate may have: differences then fit 29 bits, the lifts and
/// 2 × 2 minors 59, and the determinant's three products 119, all exact in `i64` and `i128`.
const LATTICE_BITS: i32 = 28;

/// The points as integers on one lattice of spacing 2^e, when every coordinate is a multiple
/// of a common 2^e with fewer than [`LATTICE_BITS`] bits; `None` otherwise (or for a
/// subnormal, infinite or NaN coordinate). Scaling by a power of two keeps the in-circle
/// determinant's sign.
fn on_lattice(points: [Point; 4]) -> Option<[(i64, i64); 4]> {
    let coordinates = points.map(|p| [p.x, p.y]);
    let coordinates = coordinates.as_flattened();
    // For x = m·2^(k−1075) with the 53-bit significand m: the exponents of its lowest and
    // highest set bits.
    let (mut lowest, mut highest) = (i32::MAX, i32::MIN);
    for &x in coordinates {
        if x == 0.0 {
            continue;
        }
        let bits = x.to_bits();
        let k = ((bits >> 52) & 0x7ff) as i32;
        if k == 0 || k == 0x7ff {
            return None;
        }
        let m = (bits & ((1 << 52) - 1)) | (1 << 52);
        lowest = lowest.min(k - 1075 + m.trailing_zeros() as i32);
        highest = highest.max(k - 1023);
    }
    if highest == i32::MIN {
        return Some([(0, 0); 4]);
    }
    // The scale 2^−lowest must be a normal f64 too.
    if highest - lowest >= LATTICE_BITS || !(-1022..=1023).contains(&-lowest) {
        return None;
    }
    // Exact: each quotient is an integer below 2^LATTICE_BITS, and a power-of-two scale only
    // moves the exponent.
    let scale = f64::from_bits(((1023 - lowest) as u64) << 52);
    Some(points.map(|p| ((p.x * scale) as i64, (p.y * scale) as i64)))
}

/// The in-circle determinant of lattice points, exactly: positive when d is inside the circle
/// through the counter-clockwise (a, b, c).
fn lattice_in_circle(a: (i64, i64), b: (i64, i64), c: (i64, i64), d: (i64, i64)) -> i128 {
    let [(adx, ady), (bdx, bdy), (cdx, cdy)] = [a, b, c].map(|p| (p.0 - d.0, p.1 - d.1));
    let lift = |x: i64, y: i64| i128::from(x * x + y * y);
    let minor = |x0: i64, y0: i64, x1: i64, y1: i64| i128::from(x0 * y1 - x1 * y0);
    lift(adx, ady) * minor(bdx, bdy, cdx, cdy)
        + lift(bdx, bdy) * minor(cdx, cdy, adx, ady)
        + lift(cdx, cdy) * minor(adx, ady, bdx, bdy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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

    /// A coordinate on a lattice of spacing 2^e near `base`, or an arbitrary float.
    fn coordinate() -> impl Strategy<Value = f64> {
        prop_oneof![
            (-40i64..40, -12i32..4, -3.0f64..3.0)
                .prop_map(|(k, e, base)| base.round() + k as f64 * 2f64.powi(e)),
            -3.0f64..3.0,
            (-(1i64 << 27)..(1 << 27)).prop_map(|k| k as f64),
        ]
    }

    /// Points (k, l) on a circle of radius 5 about (dx, dy) in lattice units: the 12 lattice
    /// points with k² + l² = 25.
    const ON_CIRCLE: [(f64, f64); 12] = [
        (5.0, 0.0),
        (4.0, 3.0),
        (3.0, 4.0),
        (0.0, 5.0),
        (-3.0, 4.0),
        (-4.0, 3.0),
        (-5.0, 0.0),
        (-4.0, -3.0),
        (-3.0, -4.0),
        (0.0, -5.0),
        (3.0, -4.0),
        (4.0, -3.0),
    ];

    proptest! {
        #[test]
        fn the_in_circle_test_has_robusts_sign(
            p in proptest::array::uniform8(coordinate()),
        ) {
            let [a, b, c, d] = [(0, 1), (2, 3), (4, 5), (6, 7)].map(|(i, j)| Point::new(p[i], p[j]));
            prop_assume!(is_ccw(a, b, c));
            let exact = robust::incircle(coord(a), coord(b), coord(c), coord(d));
            prop_assert_eq!(is_in_circle(a, b, c, d), exact > 0.0);
        }

        #[test]
        fn cocircular_lattice_points_are_on_the_circle_and_a_nudge_moves_them(
            picks in proptest::array::uniform4(0usize..12),
            (centre, e) in ((-1000i64..1000, -1000i64..1000), -20i32..6),
            nudge in prop_oneof![Just(0i64), Just(1), Just(-1)],
        ) {
            let h = 2f64.powi(e);
            let at = |(k, l): (f64, f64)| Point::new((centre.0 as f64 + k) * h, (centre.1 as f64 + l) * h);
            let [a, b, c, d] = picks.map(|i| at(ON_CIRCLE[i]));
            prop_assume!(is_ccw(a, b, c));
            // d moved by one lattice step towards the centre, or away, or not at all.
            let (k, l) = ON_CIRCLE[picks[3]];
            let d = Point::new(d.x - nudge as f64 * k.signum() * h, d.y - nudge as f64 * l.signum() * h);
            let exact = robust::incircle(coord(a), coord(b), coord(c), coord(d));
            prop_assert_eq!(is_in_circle(a, b, c, d), exact > 0.0);
            if nudge == 0 {
                prop_assert!(!is_in_circle(a, b, c, d), "cocircular points are not inside");
            }
        }
    }

    #[test]
    fn lattices_are_found_only_where_every_coordinate_fits() {
        let p = |x, y| Point::new(x, y);
        let dyadic = [p(0.5, 0.25), p(0.75, 0.25), p(0.75, 0.5), p(0.5, 0.5)];
        assert_eq!(on_lattice(dyadic), Some([(2, 1), (3, 1), (3, 2), (2, 2)]));
        assert_eq!(on_lattice([p(0.0, 0.0); 4]), Some([(0, 0); 4]));
        // A third is no multiple of a power of two within 28 bits of 1.
        assert_eq!(on_lattice([p(1.0 / 3.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]), None);
        // 2^28 and 1 together need 29 bits.
        assert_eq!(on_lattice([p(268435456.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]), None);
        assert!(on_lattice([p(268435455.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]).is_some());
        assert_eq!(
            on_lattice([p(f64::MIN_POSITIVE / 2.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]),
            None
        );
        // Tiny points: on a lattice of 2^−1022, and one whose scale 2^1042 would overflow.
        let tiny = f64::MIN_POSITIVE;
        let square = [p(tiny, 0.0), p(2.0 * tiny, 0.0), p(2.0 * tiny, tiny), p(0.0, tiny)];
        assert_eq!(on_lattice(square), Some([(1, 0), (2, 0), (2, 1), (0, 1)]));
        let finer = tiny * (1.0 + 2f64.powi(-20));
        assert_eq!(on_lattice([p(finer, 0.0), p(2.0 * tiny, 0.0), p(2.0 * tiny, tiny), p(0.0, tiny)]), None);
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
