//! What a solution says about each region: its area, current and mean potential, and the
//! force and torque on everything inside it.
//!
//! The force is the weighted Maxwell stress tensor (Henrotte et al. 1992; FEMM's "weighted
//! stress tensor" block integral): F = −∫ T ∇w over the domain, with T = ν (B Bᵀ − ½ |B|² I)
//! and w the piecewise linear weight that is 1 at every vertex of the closed region and 0
//! elsewhere. ∇w is nonzero only on the ring of triangles just outside the region, so the
//! region must be surrounded by air (ν = 1/μ0) for T to be the vacuum's stress; the mesh
//! follows the region's sides, so that ring never cuts into it. The torque about the region's
//! point p is −∫ ((x − p_x) (T∇w)_y − (y − p_y) (T∇w)_x), T∇w being constant on each
//! triangle.
//!
//! Axisymmetric, the same integrals run over r dA (per radian; the answer turns them about
//! the axis): the force is axial, [0, F_z], the radial parts cancelling round the turn, and
//! there is no torque. The mean of A is then weighted by r.

use super::coefficients::TriangleCoefficients;
use super::element::Element;
use super::problem::Problem;
use crate::result::{Geometry, RegionStats};

/// The figures of every region of `problem` on a solved mesh: `points` and `u` by vertex,
/// `elements`, `gradients` and `coefficients` by triangle.
pub(crate) fn measure(
    problem: &Problem<'_>,
    points: &[crate::geom::Point],
    u: &[f64],
    triangles: &[[u32; 3]],
    elements: &[Element],
    gradients: &[[f64; 2]],
    coefficients: &[TriangleCoefficients],
) -> Vec<RegionStats> {
    // A split of a slanted side leaves its midpoint within rounding of the side.
    let tolerance = 1e-9 * problem.domain().diagonal();
    let geometry = problem.geometry();
    let mut weight = vec![0.0; points.len()];
    problem
        .regions()
        .iter()
        .map(|region| {
            for (w, &p) in weight.iter_mut().zip(points) {
                *w = if region.shape.holds(p, tolerance) { 1.0 } else { 0.0 };
            }
            let (mut inside, mut integral) = (0.0, 0.0);
            let (mut force, mut torque) = ([0.0; 2], 0.0);
            for (t, (&tri, e)) in triangles.iter().zip(elements).enumerate() {
                let weights = tri.map(|v| weight[v as usize]);
                let sum = weights[0] + weights[1] + weights[2];
                // Neither inside (every corner in) nor on the ring (some corner in).
                if sum == 0.0 {
                    continue;
                }
                let centre = e.point(&[1.0 / 3.0; 3]);
                if sum == 3.0 && region.contains(centre) {
                    inside += e.weight();
                    integral += e.weight() * tri.map(|v| u[v as usize]).iter().sum::<f64>() / 3.0;
                } else if sum > 0.0 && sum < 3.0 {
                    let gw = e.gradient(weights);
                    let g = gradients[t];
                    let b = [g[1], -g[0]];
                    let nu = coefficients[t].nu(problem, g[0].hypot(g[1])).0;
                    let half = 0.5 * (b[0] * b[0] + b[1] * b[1]);
                    let tg = [
                        nu * ((b[0] * b[0] - half) * gw[0] + b[0] * b[1] * gw[1]),
                        nu * (b[1] * b[0] * gw[0] + (b[1] * b[1] - half) * gw[1]),
                    ];
                    force[0] -= e.weight() * tg[0];
                    force[1] -= e.weight() * tg[1];
                    let (x, y) = (centre.x - region.torque_about.x, centre.y - region.torque_about.y);
                    torque -= e.weight() * (x * tg[1] - y * tg[0]);
                }
            }
            if geometry == Geometry::Axisymmetric {
                // Turned about the axis, the radial pulls cancel and nothing turns.
                (force[0], torque) = (0.0, 0.0);
            }
            let area = region.shape.area();
            RegionStats {
                name: region.name.clone(),
                area,
                current: region.f.unwrap_or(0.0) * area,
                mean_a: if inside > 0.0 { integral / inside } else { 0.0 },
                force,
                torque,
            }
        })
        .collect()
}
