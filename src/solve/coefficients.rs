//! What the quadrature rule measures of k and f on each triangle, and what a material's law
//! makes of a gradient there.

use super::bh::Curve;
use super::cut;
use super::element::Element;
use super::error::SolveError;
use super::problem::Problem;
use super::quadrature::RULE;
use crate::geom::Point;
use crate::result::Geometry;

/// What the quadrature rule measures of k and f on one triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TriangleCoefficients {
    /// The rule's mean of k: the triangle's conductivity in the stiffness matrix.
    pub k: f64,
    /// The rule's mean of f².
    pub f_sq: f64,
    /// ∫ f φᵢ over the triangle's weight (its area; |T| r̄ of ∫ f φᵢ r dA axisymmetric) for
    /// the three hat functions.
    pub load: [f64; 3],
    /// The region whose curve replaces `k` on this triangle (read at its centroid).
    pub curve: Option<u32>,
    /// The rule's mean of the source s (a magnet's M/μr).
    pub source: [f64; 2],
}

impl TriangleCoefficients {
    /// Samples k and f at the rule's points of triangle `t`, or of each piece of it when a
    /// region's side crosses it (see [`cut`]).
    pub(crate) fn of(problem: &Problem<'_>, e: &Element, t: usize) -> Result<Self, SolveError> {
        let mut c = Self { k: 0.0, f_sq: 0.0, load: [0.0; 3], curve: None, source: [0.0; 2] };
        let materials = problem.has_materials();
        let axisymmetric = problem.geometry() == Geometry::Axisymmetric;
        cut::try_for_each_piece(e.p, problem.regions(), |piece, share| {
            for (l, w) in &RULE {
                let (q, hats, w) = match share {
                    None => (e.point(l), *l, *w),
                    Some(share) => {
                        let q = Point::new(
                            l[0] * piece[0].x + l[1] * piece[1].x + l[2] * piece[2].x,
                            l[0] * piece[0].y + l[1] * piece[1].y + l[2] * piece[2].y,
                        );
                        (q, e.hats(q), w * share)
                    }
                };
                let (k, f) = problem.k_and_f(q);
                c.k += w * checked_k(q, t, k)?;
                if !f.is_finite() {
                    return Err(SolveError::NonFiniteF { x: q.x, y: q.y, value: f, triangle: t });
                }
                c.f_sq += w * f * f;
                // ∫ f φ r dA over the weight |T| r̄, axisymmetric.
                let wr = if axisymmetric { w * q.x / e.radius } else { w };
                for (load, phi) in c.load.iter_mut().zip(hats) {
                    *load += wr * f * phi;
                }
                if materials {
                    let (_, source) = problem.material_at(q);
                    c.source[0] += w * source[0];
                    c.source[1] += w * source[1];
                }
            }
            Ok(())
        })?;
        if materials {
            c.curve = problem.material_at(e.point(&[1.0 / 3.0; 3])).0;
        }
        Ok(c)
    }

    /// The curve that replaces k on this triangle, if any.
    fn law<'p>(&self, problem: &'p Problem<'_>) -> Option<&'p dyn Curve> {
        self.curve.and_then(|r| problem.regions()[r as usize].curve.as_deref())
    }

    /// ν and dH/dB on a triangle whose gradient has length `b`: its curve's, or k twice.
    pub(crate) fn nu(&self, problem: &Problem<'_>, b: f64) -> (f64, f64) {
        self.law(problem).map_or((self.k, self.k), |curve| curve.nu(b))
    }

    /// The flux k ∇u − (−s_y, s_x) on a triangle of gradient `g` (H rotated, in
    /// magnetostatics): what the weak form tests, and whose normal part is continuous.
    pub(crate) fn flux(&self, problem: &Problem<'_>, g: [f64; 2]) -> [f64; 2] {
        let nu = self.law(problem).map_or(self.k, |curve| curve.nu(g[0].hypot(g[1])).0);
        [nu * g[0] + self.source[1], nu * g[1] - self.source[0]]
    }

    /// The energy density on a triangle of gradient `g`, and B·H. The energy density is
    /// ∫ H·dB along the material's law from where H = 0: from B = 0 for a curve, from the
    /// remanence Br = s/k for a magnet, so that it is ½ k |B − Br|² ≥ 0 there.
    pub(crate) fn densities(&self, problem: &Problem<'_>, g: [f64; 2]) -> (f64, f64) {
        let b_sq = g[0] * g[0] + g[1] * g[1];
        // s·B with B = (∂u/∂y, −∂u/∂x).
        let s_dot_b = self.source[0] * g[1] - self.source[1] * g[0];
        match self.law(problem) {
            Some(curve) => {
                let b = b_sq.sqrt();
                (curve.energy(b) - s_dot_b, b * curve.h(b).0 - s_dot_b)
            }
            None => {
                let s_sq = self.source[0] * self.source[0] + self.source[1] * self.source[1];
                (0.5 * self.k * b_sq - s_dot_b + 0.5 * s_sq / self.k, self.k * b_sq - s_dot_b)
            }
        }
    }
}

/// `k`, or the error naming quadrature point `q` of `triangle` where it is not finite and
/// positive.
pub(super) fn checked_k(q: Point, triangle: usize, k: f64) -> Result<f64, SolveError> {
    if k.is_finite() && k > 0.0 {
        Ok(k)
    } else {
        Err(SolveError::InvalidK { x: q.x, y: q.y, value: k, triangle })
    }
}
