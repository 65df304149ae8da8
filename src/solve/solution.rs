//! The discrete solution of one mesh: assembly, the linear or Newton solve, and the
//! quantities derived from u_h, with its distance from an exact solution.

use super::coefficients::{TriangleCoefficients, checked_k};
use super::dofs::Numbering;
use super::element::{Element, Position};
use super::error::SolveError;
use super::nonlinear::{self, Newton};
use super::problem::Problem;
use super::quadrature::RULE;

/// The discrete solution u_h and the quantities derived from it.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// u_h at every vertex, in vertex order; boundary vertices hold g.
    pub u: Vec<f64>,
    /// ½ ∫ k |∇u_h|², with k integrated by the quadrature rule; for nonlinear and magnet
    /// regions ∫ H·dB along their law from where H = 0 (J/m in magnetostatics).
    pub energy: f64,
    /// ∫ B·H − the energy: the coenergy ∫ ∫₀ᴴ B·dH for laws through the origin.
    pub coenergy: f64,
    /// What Newton did, for a nonlinear problem.
    pub newton: Option<Newton>,
    /// ∇u_h on every triangle, in triangle order: [∂u/∂x, ∂u/∂y].
    pub gradients: Vec<[f64; 2]>,
    /// How many vertices were unknowns (not on the boundary).
    pub num_unknowns: usize,
}

/// Distances between u_h and an exact solution u.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorNorms {
    /// max over vertices of |u − u_h|.
    pub max_nodal: f64,
    /// ‖u − u_h‖_L2 = (∫ (u − u_h)²)^½.
    pub l2: f64,
    /// ‖k^½ ∇(u − u_h)‖_L2 = (∫ k |∇u − ∇u_h|²)^½.
    pub energy: f64,
}

/// Solves `problem` with P1 elements on the mesh (`vertices`, `triangles`).
///
/// Triangles must be counter-clockwise and cover the problem's rectangle; a vertex is a
/// boundary vertex when one of its coordinates equals a side of the rectangle exactly.
///
/// # Errors
/// [`SolveError::InvalidK`] or [`SolveError::NonFiniteF`] naming the first bad quadrature
/// point (triangles in order), [`SolveError::NonFiniteG`] naming the first bad boundary
/// vertex, [`SolveError::DegenerateTriangle`], and the solver's failures.
///
/// # Panics
/// When a triangle refers to a vertex index ≥ `vertices.len()`.
///
/// # Example
/// ```
/// use meshfit::geom::{Point, Rect};
/// use meshfit::solve::{Problem, solve};
///
/// // The unit square split into four triangles around its centre.
/// let points = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.5, 0.5)].map(|(x, y)| Point::new(x, y));
/// let triangles = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
/// let problem = Problem::new(Rect::unit()).with_g(|x, y| 1.0 + 2.0 * x - 3.0 * y);
/// let solution = solve(&problem, &points, &triangles).unwrap();
/// assert!((solution.u[4] - 0.5).abs() < 1e-15);
/// ```
pub fn solve<P: Position>(
    problem: &Problem<'_>,
    vertices: &[P],
    triangles: &[[u32; 3]],
) -> Result<Solution, SolveError> {
    solve_with(problem, vertices, triangles, None, None)
}

/// [`solve`] with each triangle's [`TriangleCoefficients`] already measured (by triangle index), as
/// the adaptive loop keeps them from round to round: only new triangles sample k and f.
/// `start` holds u at every vertex for Newton to start from (a nonlinear problem only).
pub(crate) fn solve_with<P: Position>(
    problem: &Problem<'_>,
    vertices: &[P],
    triangles: &[[u32; 3]],
    known: Option<&[TriangleCoefficients]>,
    start: Option<&[f64]>,
) -> Result<Solution, SolveError> {
    let mut numbering = Numbering::new(problem, vertices)?;
    let mut u = std::mem::take(&mut numbering.u);
    let n = numbering.masters.len();
    let elements = (triangles.iter().enumerate())
        .map(|(t, &tri)| Element::in_geometry(problem.geometry(), vertices, tri, t))
        .collect::<Result<Vec<_>, _>>()?;
    let measured;
    let coefficients = match known {
        Some(known) => &known[..triangles.len()],
        None => {
            measured = (elements.iter().enumerate())
                .map(|(t, e)| TriangleCoefficients::of(problem, e, t))
                .collect::<Result<Vec<_>, _>>()?;
            &measured[..]
        }
    };
    let system = nonlinear::System::new(problem, triangles, &elements, coefficients, &numbering);
    let newton = if problem.is_nonlinear() {
        if let Some(start) = start {
            // Each unknown from its own vertex, so periodic partners start consistent.
            let x: Vec<f64> = numbering.masters.iter().map(|&v| start[v]).collect();
            system.scatter(&x, &mut u, |_, x| x);
        }
        Some(system.newton(&mut u)?)
    } else {
        system.linear(&mut u)?;
        None
    };

    let (mut energy, mut work) = (0.0, 0.0);
    let mut gradients = Vec::with_capacity(triangles.len());
    for ((e, c), &tri) in elements.iter().zip(coefficients).zip(triangles) {
        let g = e.field(tri.map(|v| u[v as usize]));
        if c.curve.is_none() && c.source == [0.0; 2] {
            energy += 0.5 * c.k * e.weight() * (g[0] * g[0] + g[1] * g[1]);
            work += c.k * e.weight() * (g[0] * g[0] + g[1] * g[1]);
        } else {
            let (w, b_dot_h) = c.densities(problem, g);
            energy += e.weight() * w;
            work += e.weight() * b_dot_h;
        }
        gradients.push(g);
    }
    Ok(Solution { u, energy, coenergy: work - energy, gradients, num_unknowns: n, newton })
}

impl Solution {
    /// The nodal, L2 and energy-norm distances from u_h to the exact solution `exact`, whose
    /// gradient is `gradient`.
    ///
    /// The integrals use the same 6-point rule as the assembly, and k is the problem's k at
    /// each point (not the per-triangle average used for the stiffness).
    ///
    /// # Errors
    /// [`SolveError::InvalidK`] as in [`solve`], and [`SolveError::DegenerateTriangle`].
    pub fn errors<P: Position>(
        &self,
        problem: &Problem<'_>,
        vertices: &[P],
        triangles: &[[u32; 3]],
        exact: impl Fn(f64, f64) -> f64,
        gradient: impl Fn(f64, f64) -> [f64; 2],
    ) -> Result<ErrorNorms, SolveError> {
        let max_nodal = vertices.iter().zip(&self.u).fold(0.0f64, |m, (v, u)| {
            let p = v.position();
            m.max((exact(p.x, p.y) - u).abs())
        });
        let (mut l2_sq, mut energy_sq) = (0.0, 0.0);
        for (t, &tri) in triangles.iter().enumerate() {
            let e = Element::new(vertices, tri, t)?;
            let uh = tri.map(|v| self.u[v as usize]);
            let gh = self.gradients[t];
            let (mut l2_t, mut energy_t) = (0.0, 0.0);
            for (l, w) in &RULE {
                let q = e.point(l);
                let k = checked_k(q, t, problem.k_at(q))?;
                let d = exact(q.x, q.y) - (l[0] * uh[0] + l[1] * uh[1] + l[2] * uh[2]);
                let g = gradient(q.x, q.y);
                let (dx, dy) = (g[0] - gh[0], g[1] - gh[1]);
                l2_t += w * d * d;
                energy_t += w * k * (dx * dx + dy * dy);
            }
            l2_sq += e.area() * l2_t;
            energy_sq += e.area() * energy_t;
        }
        Ok(ErrorNorms { max_nodal, l2: l2_sq.sqrt(), energy: energy_sq.sqrt() })
    }
}
