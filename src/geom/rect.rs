//! The rectangle a mesh covers, checked where it is made: finite, not empty, not too narrow
//! for the mesh's floors and not so large that the exact predicates overflow.

use super::point::Point;
use std::fmt;

/// The largest coordinate magnitude a rectangle may have.
///
/// The in-circle predicate works with fourth powers of coordinate differences; keeping
/// |coordinate| ≤ 1e60 keeps those finite.
pub const MAX_COORDINATE: f64 = 1e60;

/// How small a side may be relative to the largest coordinate: below this, midpoints of short
/// edges round onto their endpoints long before any useful refinement.
pub const MIN_RELATIVE_SIDE: f64 = 1e-9;

/// The shortest side a rectangle may have. The predicates multiply up to four coordinate
/// differences; with edges down to 1e-9 of a side of 1e-30, those products stay far above
/// the subnormal range, where even exact predicates lose their guarantees.
pub const MIN_SIDE: f64 = 1e-30;

/// The closed rectangle [x0, x1] × [y0, y1] with x0 < x1 and y0 < y1, all finite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

/// Why a rectangle was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RectError {
    /// A bound is NaN or infinite.
    #[error("domain bound {name} is not finite")]
    NonFinite {
        /// Which bound: "a", "b", "c" or "d".
        name: &'static str,
    },
    /// A bound is beyond ±[`MAX_COORDINATE`].
    #[error("domain bound {name} = {value} is beyond ±1e60")]
    TooLarge {
        /// Which bound.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The interval on one axis is empty or reversed.
    #[error("domain is empty on {axis}: need {axis}0 < {axis}1, got [{lo}, {hi}]")]
    Empty {
        /// "x" or "y".
        axis: &'static str,
        /// The lower bound given.
        lo: f64,
        /// The upper bound given.
        hi: f64,
    },
    /// One side is too short to refine at the magnitude of its coordinates.
    #[error("domain is too narrow on {axis}: the side {side} is below 1e-9 times the coordinates' magnitude")]
    TooNarrow {
        /// "x" or "y".
        axis: &'static str,
        /// The side's length.
        side: f64,
    },
}

impl Rect {
    /// The rectangle [a, b] × [c, d].
    ///
    /// # Errors
    /// When a bound is not finite or beyond ±1e60, when a ≥ b or c ≥ d, or when a side is
    /// shorter than 1e-30 or than 1e-9 times the largest coordinate magnitude.
    pub fn new(a: f64, b: f64, c: f64, d: f64) -> Result<Self, RectError> {
        for (name, value) in [("a", a), ("b", b), ("c", c), ("d", d)] {
            if !value.is_finite() {
                return Err(RectError::NonFinite { name });
            }
            if value.abs() > MAX_COORDINATE {
                return Err(RectError::TooLarge { name, value });
            }
        }
        // `!(a < b)` also catches a == b; NaN is excluded above.
        if a >= b {
            return Err(RectError::Empty { axis: "x", lo: a, hi: b });
        }
        if c >= d {
            return Err(RectError::Empty { axis: "y", lo: c, hi: d });
        }
        let magnitude = a.abs().max(b.abs()).max(c.abs()).max(d.abs());
        for (axis, side) in [("x", b - a), ("y", d - c)] {
            if side < MIN_RELATIVE_SIDE * magnitude || side < MIN_SIDE {
                return Err(RectError::TooNarrow { axis, side });
            }
        }
        Ok(Self { x0: a, x1: b, y0: c, y1: d })
    }

    /// The unit square [0, 1] × [0, 1].
    pub const fn unit() -> Self {
        Self { x0: 0.0, x1: 1.0, y0: 0.0, y1: 1.0 }
    }

    /// Lower x bound (a).
    pub const fn x0(&self) -> f64 {
        self.x0
    }
    /// Upper x bound (b).
    pub const fn x1(&self) -> f64 {
        self.x1
    }
    /// Lower y bound (c).
    pub const fn y0(&self) -> f64 {
        self.y0
    }
    /// Upper y bound (d).
    pub const fn y1(&self) -> f64 {
        self.y1
    }

    /// The corners P1 = (a, c), P2 = (b, c), P3 = (b, d), P4 = (a, d), counter-clockwise.
    pub const fn corners(&self) -> [Point; 4] {
        [
            Point::new(self.x0, self.y0),
            Point::new(self.x1, self.y0),
            Point::new(self.x1, self.y1),
            Point::new(self.x0, self.y1),
        ]
    }

    /// Whether `p` lies in the closed rectangle, sides included (false for NaN).
    pub fn contains(&self, p: Point) -> bool {
        self.x0() <= p.x && p.x <= self.x1() && self.y0() <= p.y && p.y <= self.y1()
    }

    /// Width × height.
    pub fn area(&self) -> f64 {
        (self.x1 - self.x0) * (self.y1 - self.y0)
    }

    /// Length of the diagonal.
    pub fn diagonal(&self) -> f64 {
        (self.x1 - self.x0).hypot(self.y1 - self.y0)
    }

    /// Whether `p` lies on the rectangle's boundary (exactly).
    pub fn is_on_boundary(&self, p: Point) -> bool {
        let in_x = self.x0 <= p.x && p.x <= self.x1;
        let in_y = self.y0 <= p.y && p.y <= self.y1;
        ((p.x == self.x0 || p.x == self.x1) && in_y) || ((p.y == self.y0 || p.y == self.y1) && in_x)
    }
}

impl fmt::Display for Rect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{}, {}] x [{}, {}]", self.x0, self.x1, self.y0, self.y1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rect_rejects_empty_reversed_and_non_finite_bounds() {
        assert!(matches!(Rect::new(1.0, 1.0, 0.0, 1.0), Err(RectError::Empty { axis: "x", .. })));
        assert!(matches!(Rect::new(0.0, 1.0, 2.0, 1.0), Err(RectError::Empty { axis: "y", .. })));
        assert!(matches!(Rect::new(f64::NAN, 1.0, 0.0, 1.0), Err(RectError::NonFinite { name: "a" })));
        assert!(matches!(Rect::new(0.0, 1e61, 0.0, 1.0), Err(RectError::TooLarge { name: "b", .. })));
        assert!(matches!(Rect::new(1e9, 1e9 + 1e-3, 0.0, 1.0), Err(RectError::TooNarrow { axis: "x", .. })));
        assert!(matches!(Rect::new(0.0, 1e-100, 0.0, 1.0), Err(RectError::TooNarrow { axis: "x", .. })));
        assert!(Rect::new(-3.0, 3.0, -3.0, 3.0).is_ok());
    }
}
