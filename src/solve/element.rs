//! The P1 element: a triangle's corners, its area and the gradients of its hat functions.

use super::error::SolveError;
use crate::geom::predicates::signed_area_x2;
use crate::geom::{Point, Vertex};

/// Anything with a position in the plane: [`Point`] and [`Vertex`].
pub trait Position {
    /// The position.
    fn position(&self) -> Point;
}

impl Position for Point {
    fn position(&self) -> Point {
        *self
    }
}

impl Position for Vertex {
    fn position(&self) -> Point {
        self.point()
    }
}

/// A triangle's corners, its area and the gradients of its three hat functions.
pub struct Element {
    pub(super) p: [Point; 3],
    pub(super) area: f64,
    pub(super) grad: [[f64; 2]; 3],
}

impl Element {
    /// Triangle `t` with corners `tri`.
    ///
    /// # Errors
    /// [`SolveError::DegenerateTriangle`] unless it is strictly counter-clockwise.
    pub fn new<P: Position>(vertices: &[P], tri: [u32; 3], t: usize) -> Result<Self, SolveError> {
        let p = tri.map(|v| vertices[v as usize].position());
        // robust's orient2d: the sign is exact, so no rounding lets a folded triangle in.
        let det = signed_area_x2(p[0], p[1], p[2]);
        if det.is_nan() || det <= 0.0 {
            return Err(SolveError::DegenerateTriangle { triangle: t, area: det / 2.0 });
        }
        let grad = std::array::from_fn(|i| {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            [(p[j].y - p[k].y) / det, (p[k].x - p[j].x) / det]
        });
        Ok(Self { p, area: det / 2.0, grad })
    }

    pub(super) fn point(&self, l: &[f64; 3]) -> Point {
        Point::new(
            l[0] * self.p[0].x + l[1] * self.p[1].x + l[2] * self.p[2].x,
            l[0] * self.p[0].y + l[1] * self.p[1].y + l[2] * self.p[2].y,
        )
    }

    /// ∇ of the linear function with `values` at the corners.
    pub fn gradient(&self, values: [f64; 3]) -> [f64; 2] {
        let mut g = [0.0; 2];
        for (v, grad) in values.iter().zip(&self.grad) {
            g[0] += v * grad[0];
            g[1] += v * grad[1];
        }
        g
    }

    /// The three hat functions at `q`: its barycentric coordinates.
    pub(super) fn hats(&self, q: Point) -> [f64; 3] {
        std::array::from_fn(|i| {
            let p = self.p[i];
            1.0 + self.grad[i][0] * (q.x - p.x) + self.grad[i][1] * (q.y - p.y)
        })
    }

    /// The triangle's area.
    pub(crate) fn area(&self) -> f64 {
        self.area
    }
}
