//! What a solution says about each circuit: its flux linkage and its inductances.
//!
//! A circuit's coil sides carry f = I · turns / area each (turns signed by direction), so the
//! load vector is I · b with bᵢ = Σ_sides turns / area · ∫_side φᵢ, and the flux linkage per
//! metre is λ = Σ_sides turns / area · ∫_side A = b · u. The apparent inductance is λ / I. The
//! incremental one differentiates the discrete equations R(u) = I b + … at the solution:
//! K_t du = b dI with K_t the Jacobian Newton factors (the stiffness of a linear problem), so
//! dλ/dI = bᵀ K_t⁻¹ b, one solve with the factor of the final mesh and no second nonlinear
//! solve. For a linear device without magnets λ = I bᵀ K⁻¹ b, and the two agree to rounding.
//! Axisymmetric, the integrals are over r dA, so λ and the inductances are per radian: the
//! answer turns them about the axis (2π).

use super::cholesky::Analysis;
use super::coefficients::TriangleCoefficients;
use super::dofs::Numbering;
use super::element::Element;
use super::error::SolveError;
use super::nonlinear::System;
use super::problem::Problem;
use crate::geom::Point;
use crate::result::{CircuitStats, Geometry};
use std::collections::BTreeMap;

/// The figures of every circuit of `problem` on a solved mesh: `points` and `u` by vertex,
/// `elements` and `coefficients` by triangle.
///
/// A triangle belongs to the coil side that holds its centroid and sets its f (the topmost,
/// as regions apply): the loop's meshes follow every side, so each triangle is wholly in or
/// out of each region.
///
/// # Errors
/// The factorisation's, when the final mesh's tangent system is not positive definite.
pub(crate) fn measure(
    problem: &Problem<'_>,
    points: &[Point],
    u: &[f64],
    triangles: &[[u32; 3]],
    elements: &[Element],
    coefficients: &[TriangleCoefficients],
) -> Result<BTreeMap<String, CircuitStats>, SolveError> {
    let circuits = problem.circuits();
    if circuits.is_empty() {
        return Ok(BTreeMap::new());
    }
    // b of each circuit, by vertex.
    let mut b = vec![vec![0.0; points.len()]; circuits.len()];
    for (e, &tri) in elements.iter().zip(triangles) {
        let centre = e.point(&[1.0 / 3.0; 3]);
        let side = problem.regions().iter().rev().find(|r| r.f.is_some() && r.contains(centre));
        let Some((coil, area)) = side.and_then(|r| r.coil.map(|c| (c, r.shape.area()))) else { continue };
        for (i, v) in tri.into_iter().enumerate() {
            // ∫ φᵢ dA = |T| / 3; axisymmetric ∫ φᵢ r dA = |T| (3 r̄ + rᵢ) / 12.
            let integral = match problem.geometry() {
                Geometry::Planar => e.area() / 3.0,
                Geometry::Axisymmetric => e.area() * (3.0 * e.radius + e.p[i].x) / 12.0,
            };
            b[coil.circuit][v as usize] += coil.turns / area * integral;
        }
    }
    let numbering = Numbering::new(problem, points)?;
    let system = System::new(problem, triangles, elements, coefficients, &numbering);
    let (unknown, sign, n) = (system.unknown, system.sign, system.unknowns);
    let mut entries = Vec::with_capacity(6 * triangles.len());
    system.residual(u, Some(&mut entries));
    let rhs: Vec<Vec<f64>> = (b.iter())
        .map(|b| {
            let mut rhs = vec![0.0; n];
            for ((&bv, index), s) in b.iter().zip(unknown).zip(sign) {
                if let Some(i) = index {
                    rhs[*i] += s * bv;
                }
            }
            rhs
        })
        .collect();
    let solved = if n == 0 { rhs } else { Analysis::new(n, &entries)?.solve_many(entries, rhs)? };
    Ok((circuits.iter().zip(&b).zip(&solved))
        .map(|((circuit, b), x)| {
            let flux_linkage: f64 = b.iter().zip(u).map(|(b, u)| b * u).sum();
            let incremental: f64 = (b.iter().zip(unknown).zip(sign))
                .filter_map(|((b, index), s)| index.map(|i| b * s * x[i]))
                .sum();
            let stats = CircuitStats {
                current: circuit.current,
                flux_linkage,
                inductance: (circuit.current != 0.0).then(|| flux_linkage / circuit.current),
                incremental_inductance: incremental,
            };
            (circuit.name.clone(), stats)
        })
        .collect())
}
