//! P1 finite elements on a triangle mesh: −∇·(k ∇u) = f in a rectangle; u = g on its Dirichlet
//! sides, zero flux on its Neumann sides, u equal or opposite across a periodic pair, an
//! asymptotic condition on its open sides; k a constant, an expression, or a B–H curve of |∇u|
//! (nonlinear, by Newton). Planar, or axisymmetric in (r, z) for A_φ (see `element`); coils on
//! circuits give their flux linkage and inductances (`circuits`), and `materials` is the
//! built-in library of laws.
//!
//! # Usage
//! Describe the problem with [`Problem`], then call [`solve`] with the mesh's vertices (either
//! [`Point`](crate::geom::Point)s or [`Vertex`](crate::geom::Vertex)es, so a [`geom::Mesh`](crate::geom::Mesh) and a
//! [`RunResult`](crate::result::RunResult) both work) and its counter-clockwise triangles,
//! or [`adapt`] to refine and solve in rounds on a mesh that follows the regions' sides.
//! [`Solution::errors`] measures the result against a known exact solution.
//!
//! # Method
//! - Unknowns are the vertices not on a Dirichlet side (exactly: x = x0, x1 or y = y0, y1),
//!   numbered in vertex order; a periodic partner shares its partner's unknown (`Numbering`).
//!   Dirichlet vertices take u = g and are eliminated: their columns move to the right-hand
//!   side.
//! - Every integral uses the 6-point, degree-4 rule of Dunavant (1985), whose points lie
//!   strictly inside each triangle. A triangle that a rectangle region's side crosses (on a
//!   mesh that does not follow it) is cut along the side into pieces, and the rule is applied
//!   on each, so a region's k and f count with their exact share of the triangle's area. The
//!   load vector ∫ f φᵢ is exact for f of degree ≤ 3 (linear f included) and for region values.
//! - A nonlinear problem is solved by Newton's method with a line search (`nonlinear`); each
//!   step is a linear solve of the same kind.
//! - The symmetric positive definite system is factorised by a supernodal sparse Cholesky
//!   (LLᵀ, `cholesky`): `faer` orders it (approximate minimum degree) and finds the
//!   supernodes, and the numbers are computed by dense kernels of our own.
//!
//! # Guarantees
//! - Deterministic bit for bit: triangles are assembled in index order, the matrix entries
//!   are sorted by (column, row) with a stable sort and duplicates summed in assembly order,
//!   and the factorisation's every sum is a `mul_add` chain in a fixed order, so the AVX2
//!   build that runs where the CPU has it gives the bits of the portable one.
//! - Linear g with f = 0 and constant k is reproduced to rounding (the patch test).
//!
//! # Limitations
//! - Robin data only as open sides' asymptotic condition; every problem needs one Dirichlet or
//!   open side.
//! - On a mesh that does not follow a region (a library caller's own), a side that cuts a
//!   triangle is integrated exactly, but u_h stays linear across it; a curve's or a magnet's
//!   triangle takes the material at its centroid. [`adapt`]'s meshes follow every side.
//! - Needle triangles amplify rounding: the patch-test error grows like ε divided by the
//!   smallest height/length ratio, which meshes from the Recursive method drive to ~1e-9 by
//!   a thousand vertices (error ~1e-8 there, against ~1e-14 on Delaunay meshes).
//! - Vertices that no triangle uses are unknowns with an empty row, so the factorisation
//!   fails with [`SolveError::NotPositiveDefinite`].

mod adapt;
mod bh;
mod cholesky;
mod circuits;
mod coefficients;
mod cut;
mod dofs;
mod element;
mod error;
mod fields;
pub mod materials;
mod nonlinear;
mod periodic;
mod physics;
mod polygon;
mod problem;
mod quadrature;
mod regions;
mod residual;
mod solution;
#[cfg(test)]
mod tests;

pub use adapt::{Adapted, Exact, INITIAL_VERTICES, Indicator, Settings, SolveObserver, adapt};
pub use bh::{BhCurve, Curve, CurveError};
pub use element::{Element, Position};
pub use error::SolveError;
#[cfg(test)]
pub(crate) use fields::flux_density;
pub use nonlinear::{MAX_NEWTON_ITERATIONS, NEWTON_TOLERANCE, Newton};
pub use physics::MU_0;
pub use polygon::{MAX_POLYGON_POINTS, Polygon, PolygonError, arc_points};
pub use problem::{Boundary, Circuit, Coil, OutsideDomain, Problem, Region, Shape, Side};
pub use solution::{ErrorNorms, Solution, solve};
// A solution's report is data of its result, which knows nothing of the solver.
pub use crate::result::{CircuitStats, Physics, RegionStats, SolveStats, Step};
