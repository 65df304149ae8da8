//! Points of the plane, and vertices: points that carry a value z.

/// A point of the plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Abscissa.
    pub x: f64,
    /// Ordinate.
    pub y: f64,
}

impl Point {
    /// The point (x, y).
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    /// The correctly rounded midpoint of `self` and `other`.
    ///
    /// `(a + b) * 0.5` rounds once (the halving is exact), so the result is the representable
    /// point nearest the true midpoint, independent of argument order.
    pub fn midpoint(self, other: Point) -> Point {
        Point::new((self.x + other.x) * 0.5, (self.y + other.y) * 0.5)
    }

    /// Squared Euclidean distance.
    pub fn distance_sq(self, other: Point) -> f64 {
        let dx = other.x - self.x;
        let dy = other.y - self.y;
        dx * dx + dy * dy
    }
}

/// A mesh vertex: its position and the value of F there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    /// Abscissa.
    pub x: f64,
    /// Ordinate.
    pub y: f64,
    /// F(x, y).
    pub z: f64,
}

impl Vertex {
    /// The vertex's position.
    pub const fn point(self) -> Point {
        Point::new(self.x, self.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn midpoint_is_symmetric_and_exact_for_dyadic_points() {
        let a = Point::new(0.1, -7.25);
        let b = Point::new(3.3, 2.0);
        assert_eq!(a.midpoint(b), b.midpoint(a));
        assert_eq!(Point::new(0.0, 0.0).midpoint(Point::new(1.0, 0.5)), Point::new(0.5, 0.25));
    }
}
