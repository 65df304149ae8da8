//! P1 finite elements on a triangle mesh: −∇·(k ∇u) = f in a rectangle; u = g on its Dirichlet
//! sides, zero flux on its Neumann sides, u equal or opposite across a periodic pair; k a
//! constant, an expression, or a B–H curve of |∇u| (nonlinear, by Newton).
//!
//! # Usage
//! Describe the problem with [`Problem`], then call [`solve`] with the mesh's vertices (either
//! [`Point`]s or [`Vertex`]es, so a [`geom::Mesh`](crate::geom::Mesh) and a
//! [`MeshResult`](crate::result::MeshResult) both work) and its counter-clockwise triangles,
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
//! - No Robin data; every problem needs one Dirichlet side.
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
mod cut;
mod nonlinear;
mod periodic;
mod problem;
mod quadrature;
mod regions;
mod residual;
#[cfg(test)]
mod tests;

pub use adapt::{Adapted, Exact, INITIAL_VERTICES, Indicator, Settings, SolveStats, Step, adapt};
pub use bh::{BhCurve, Curve, CurveError};
pub use nonlinear::{MAX_NEWTON_ITERATIONS, NEWTON_TOLERANCE, Newton};
pub use problem::{Boundary, Polygon, Problem, Region, Shape, Side};
pub use regions::RegionStats;

use crate::geom::predicates::signed_area_x2;
use crate::geom::{ConstrainedError, Point, Vertex};
use faer::sparse::FaerError;
use quadrature::RULE;
use std::collections::HashMap;

/// The magnetic constant μ0 in H/m (CODATA 2018).
pub const MU_0: f64 = 1.256_637_062_12e-6;

/// What u stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Physics {
    /// −∇·(k ∇u) = f as given.
    #[default]
    Poisson,
    /// u is the vector potential A_z (Wb/m): k = 1/(μ0 μr), f = J_z (A/m²), and the flux
    /// density is B = (∂A/∂y, −∂A/∂x) in tesla.
    Magnetostatic,
}

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

/// Why a problem could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// k is zero, negative or not finite at a quadrature point.
    #[error("k = {value} at ({x}, {y}); k must be finite and positive")]
    InvalidK {
        /// Abscissa of the quadrature point.
        x: f64,
        /// Ordinate of the quadrature point.
        y: f64,
        /// The value found.
        value: f64,
        /// The triangle's index (for library callers; messages name the point).
        triangle: usize,
    },
    /// f is not finite at a quadrature point.
    #[error("f = {value} at ({x}, {y}) is not finite")]
    NonFiniteF {
        /// Abscissa of the quadrature point.
        x: f64,
        /// Ordinate of the quadrature point.
        y: f64,
        /// The value found.
        value: f64,
        /// The triangle's index.
        triangle: usize,
    },
    /// g is not finite at a boundary vertex.
    #[error("g = {value} at boundary point ({x}, {y}) is not finite")]
    NonFiniteG {
        /// Abscissa of the vertex.
        x: f64,
        /// Ordinate of the vertex.
        y: f64,
        /// The value found.
        value: f64,
        /// The vertex's index.
        vertex: usize,
    },
    /// The error estimate of a triangle overflows f64: k, f or the solution is too large.
    #[error(
        "the error estimate near ({x}, {y}) overflows: k, f or the \
         solution is too large for 64-bit floats; scale the problem"
    )]
    Overflow {
        /// Abscissa of the triangle's centroid.
        x: f64,
        /// Ordinate of the triangle's centroid.
        y: f64,
        /// The triangle's index.
        triangle: usize,
    },
    /// A triangle is not counter-clockwise with positive area.
    #[error("triangle {triangle} has signed area {area}; triangles must be counter-clockwise")]
    DegenerateTriangle {
        /// The triangle's index.
        triangle: usize,
        /// Its signed area.
        area: f64,
    },
    /// The stiffness matrix is not numerically positive definite (for instance an interior
    /// vertex that no triangle uses).
    #[error("the stiffness matrix is not positive definite (pivot {pivot} of {unknowns})")]
    NotPositiveDefinite {
        /// The failing pivot, in the solver's (permuted) order.
        pivot: usize,
        /// The number of unknowns.
        unknowns: usize,
    },
    /// The sparse solver could not allocate or index the factor.
    #[error("the sparse factorisation failed: {0}")]
    Factorisation(FaerError),
    /// The regions' sides do not make a mesh.
    #[error(transparent)]
    Regions(#[from] ConstrainedError),
    /// A vertex on a periodic side has no vertex at the matching point of the other side.
    #[error("the vertex ({x}, {y}) on a periodic side has no partner on the opposite side")]
    Unmatched {
        /// Abscissa.
        x: f64,
        /// Ordinate.
        y: f64,
    },
}

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

/// A triangle's corners, its area and the gradients of its three hat functions.
pub struct Element {
    p: [Point; 3],
    area: f64,
    grad: [[f64; 2]; 3],
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

    fn point(&self, l: &[f64; 3]) -> Point {
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
    fn hats(&self, q: Point) -> [f64; 3] {
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

/// What the quadrature rule measures of k and f on one triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Coefficients {
    /// The rule's mean of k: the triangle's conductivity in the stiffness matrix.
    pub k: f64,
    /// The rule's mean of f².
    pub f_sq: f64,
    /// ∫ f φᵢ / area for the three hat functions.
    pub load: [f64; 3],
    /// The region whose curve replaces `k` on this triangle (read at its centroid).
    pub curve: Option<u32>,
    /// The rule's mean of the source s (a magnet's M/μr).
    pub source: [f64; 2],
}

impl Coefficients {
    /// Samples k and f at the rule's points of triangle `t`, or of each piece of it when a
    /// region's side crosses it (see [`cut`]).
    pub(crate) fn of(problem: &Problem<'_>, e: &Element, t: usize) -> Result<Self, SolveError> {
        let mut c = Self { k: 0.0, f_sq: 0.0, load: [0.0; 3], curve: None, source: [0.0; 2] };
        let materials = problem.has_materials();
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
                for (load, phi) in c.load.iter_mut().zip(hats) {
                    *load += w * f * phi;
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

fn checked_k(q: Point, triangle: usize, k: f64) -> Result<f64, SolveError> {
    if k.is_finite() && k > 0.0 {
        Ok(k)
    } else {
        Err(SolveError::InvalidK { x: q.x, y: q.y, value: k, triangle })
    }
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

/// [`solve`] with each triangle's [`Coefficients`] already measured (by triangle index), as
/// the adaptive loop keeps them from round to round: only new triangles sample k and f.
/// `start` holds u at every vertex for Newton to start from (a nonlinear problem only).
pub(crate) fn solve_with<P: Position>(
    problem: &Problem<'_>,
    vertices: &[P],
    triangles: &[[u32; 3]],
    known: Option<&[Coefficients]>,
    start: Option<&[f64]>,
) -> Result<Solution, SolveError> {
    let Numbering { unknown, sign, mut u, masters } = Numbering::new(problem, vertices)?;
    let n = masters.len();
    let elements = (triangles.iter().enumerate())
        .map(|(t, &tri)| Element::new(vertices, tri, t))
        .collect::<Result<Vec<_>, _>>()?;
    let measured;
    let coefficients = match known {
        Some(known) => &known[..triangles.len()],
        None => {
            measured = (elements.iter().enumerate())
                .map(|(t, e)| Coefficients::of(problem, e, t))
                .collect::<Result<Vec<_>, _>>()?;
            &measured[..]
        }
    };
    let system = nonlinear::System {
        problem,
        triangles,
        elements: &elements,
        coefficients,
        unknown: &unknown,
        sign: &sign,
        unknowns: masters.len(),
    };
    let newton = if problem.is_nonlinear() {
        if let Some(start) = start {
            // Each unknown from its own vertex, so periodic partners start consistent.
            let x: Vec<f64> = masters.iter().map(|&v| start[v]).collect();
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
        let g = e.gradient(tri.map(|v| u[v as usize]));
        if c.curve.is_none() && c.source == [0.0; 2] {
            energy += 0.5 * c.k * e.area * (g[0] * g[0] + g[1] * g[1]);
            work += c.k * e.area * (g[0] * g[0] + g[1] * g[1]);
        } else {
            let (w, b_dot_h) = c.densities(problem, g);
            energy += e.area * w;
            work += e.area * b_dot_h;
        }
        gradients.push(g);
    }
    Ok(Solution { u, energy, coenergy: work - energy, gradients, num_unknowns: n, newton })
}

/// Which vertices are unknowns: one per vertex off the Dirichlet sides, except that a vertex
/// on the right (top) side of a periodic pair shares its left (bottom) partner's, with the
/// pair's sign; a corner on two pairs goes through both to the bottom-left one.
struct Numbering {
    /// The unknown of each vertex, `None` on a Dirichlet side.
    unknown: Vec<Option<usize>>,
    /// u at the vertex = sign · the unknown.
    sign: Vec<f64>,
    /// g at the Dirichlet vertices, 0 elsewhere.
    u: Vec<f64>,
    /// The vertex that owns each unknown.
    masters: Vec<usize>,
}

impl Numbering {
    fn new<P: Position>(problem: &Problem<'_>, vertices: &[P]) -> Result<Self, SolveError> {
        let (domain, boundary) = (problem.domain(), problem.boundary());
        let mut numbering = Self {
            unknown: vec![None; vertices.len()],
            sign: vec![1.0; vertices.len()],
            u: vec![0.0; vertices.len()],
            masters: Vec::new(),
        };
        // Each vertex's partner across each periodic pair, found by its exact coordinate.
        let index = |on: &dyn Fn(Point) -> bool, along: fn(Point) -> f64| -> HashMap<u64, usize> {
            let on_side = vertices.iter().enumerate().filter(|(_, p)| on(p.position()));
            on_side.map(|(v, p)| ((along(p.position()) + 0.0).to_bits(), v)).collect()
        };
        let across_x = boundary.across_x().map(|sign| (sign, index(&|p| p.x == domain.x0(), |p| p.y)));
        let across_y = boundary.across_y().map(|sign| (sign, index(&|p| p.y == domain.y0(), |p| p.x)));
        // The vertex whose unknown `v` takes, and the sign.
        let master = |v: usize| -> Result<(usize, f64), SolveError> {
            let (mut v, mut sign) = (v, 1.0);
            let p = vertices[v].position();
            if let Some((s, left)) = &across_x
                && p.x == domain.x1()
            {
                v = *left.get(&(p.y + 0.0).to_bits()).ok_or(SolveError::Unmatched { x: p.x, y: p.y })?;
                sign *= s;
            }
            let q = vertices[v].position();
            if let Some((s, bottom)) = &across_y
                && q.y == domain.y1()
            {
                v = *bottom.get(&(q.x + 0.0).to_bits()).ok_or(SolveError::Unmatched { x: q.x, y: q.y })?;
                sign *= s;
            }
            Ok((v, sign))
        };
        // Partners take their master's unknown once every master has one.
        let mut partners = Vec::new();
        for (v, vertex) in vertices.iter().enumerate() {
            let p = vertex.position();
            if problem.is_dirichlet(p) {
                let g = problem.g_at(p);
                if !g.is_finite() {
                    return Err(SolveError::NonFiniteG { x: p.x, y: p.y, value: g, vertex: v });
                }
                numbering.u[v] = g;
                continue;
            }
            match master(v)? {
                (m, _) if m == v => {
                    numbering.unknown[v] = Some(numbering.masters.len());
                    numbering.masters.push(v);
                }
                (m, sign) => partners.push((v, m, sign)),
            }
        }
        for (v, m, sign) in partners {
            numbering.unknown[v] = numbering.unknown[m];
            numbering.sign[v] = sign;
        }
        Ok(numbering)
    }
}

/// Solves A x = b for the symmetric positive definite A given by its lower-triangle
/// `entries` (column, row, value); duplicates are summed.
fn solve_spd(n: usize, entries: Vec<(usize, usize, f64)>, b: Vec<f64>) -> Result<Vec<f64>, SolveError> {
    if n == 0 {
        return Ok(b);
    }
    cholesky::Analysis::new(n, &entries)?.solve(entries, b)
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
            l2_sq += e.area * l2_t;
            energy_sq += e.area * energy_t;
        }
        Ok(ErrorNorms { max_nodal, l2: l2_sq.sqrt(), energy: energy_sq.sqrt() })
    }
}
