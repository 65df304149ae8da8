//! The P1 element: a triangle's corners, its area and the gradients of its hat functions,
//! and what the weak form reads of them in the problem's geometry.
//!
//! Planar, the field of u is ∇u and integrals are over area. Axisymmetric, x is r and y is z,
//! u is A_φ, and B = (−∂A/∂z, ∂A/∂r + A/r) = (g_y, −g_x) for g = −(∂A/∂r + A/r, ∂A/∂z);
//! integrals are per radian, over r dA. The element takes A/r as the mean of A at the corners
//! over r̄, the centroid's r, and weighs the triangle by |T| r̄: exact for A = c·r, which is A
//! near the axis, and second order elsewhere. Its B is then constant on each triangle, as ∇u
//! is planar, so the linear and Newton solves, the energy, the fluxes and the forces are the
//! planar ones with `d` for the hat functions' gradients and `weight()` for the area.

use super::error::SolveError;
use crate::geom::predicates::signed_area_x2;
use crate::geom::{Point, Vertex};
use crate::result::Geometry;

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
    /// What each hat function adds to the field g: its gradient, planar.
    pub(super) d: [[f64; 2]; 3],
    /// r̄ axisymmetric, 1 planar: the triangle weighs |T| r̄ in the weak form's integrals.
    pub(super) radius: f64,
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
        Ok(Self { p, area: det / 2.0, grad, d: grad, radius: 1.0 })
    }

    /// Triangle `t` with corners `tri` in `geometry`; see the module's documentation.
    ///
    /// # Errors
    /// As [`Element::new`].
    pub fn in_geometry<P: Position>(
        geometry: Geometry,
        vertices: &[P],
        tri: [u32; 3],
        t: usize,
    ) -> Result<Self, SolveError> {
        let mut e = Self::new(vertices, tri, t)?;
        if geometry == Geometry::Axisymmetric {
            let r = (e.p[0].x + e.p[1].x + e.p[2].x) / 3.0;
            e.d = e.grad.map(|[gr, gz]| [-(gr + 1.0 / (3.0 * r)), -gz]);
            e.radius = r;
        }
        Ok(e)
    }

    pub(super) fn point(&self, l: &[f64; 3]) -> Point {
        Point::new(
            l[0] * self.p[0].x + l[1] * self.p[1].x + l[2] * self.p[2].x,
            l[0] * self.p[0].y + l[1] * self.p[1].y + l[2] * self.p[2].y,
        )
    }

    /// The field g of the linear function with `values` at the corners: ∇u planar (B is
    /// (g_y, −g_x) in magnetostatics, either geometry).
    pub fn field(&self, values: [f64; 3]) -> [f64; 2] {
        combine(values, &self.d)
    }

    /// ∇ of the linear function with `values` at the corners.
    pub fn gradient(&self, values: [f64; 3]) -> [f64; 2] {
        combine(values, &self.grad)
    }

    /// The three hat functions at `q`: its barycentric coordinates.
    pub(crate) fn hats(&self, q: Point) -> [f64; 3] {
        std::array::from_fn(|i| {
            let p = self.p[i];
            1.0 + self.grad[i][0] * (q.x - p.x) + self.grad[i][1] * (q.y - p.y)
        })
    }

    /// The triangle's area.
    pub(crate) fn area(&self) -> f64 {
        self.area
    }

    /// What the triangle weighs in the weak form: its area, or |T| r̄ axisymmetric.
    pub(crate) fn weight(&self) -> f64 {
        self.area * self.radius
    }
}

/// Σᵢ valuesᵢ · vectorsᵢ, summed in corner order.
fn combine(values: [f64; 3], vectors: &[[f64; 2]; 3]) -> [f64; 2] {
    let mut g = [0.0; 2];
    for (v, d) in values.iter().zip(vectors) {
        g[0] += v * d[0];
        g[1] += v * d[1];
    }
    g
}
