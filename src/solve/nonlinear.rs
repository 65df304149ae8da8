//! The discrete system on one mesh: assembled once for a linear problem, by Newton's method
//! with a line search when a region's k is a curve ν(|∇u|).
//!
//! With B = |∇u| constant on each P1 triangle, the residual of vertex i is
//! Rᵢ = Σ_T |T| (q_T · ∇φᵢ − ∫_T f φᵢ / |T|), q = ν(B) ∇u + (s_y, −s_x), and its Jacobian
//! |T| (ν ∇φᵢ·∇φⱼ + (dH/dB − ν)(ĝ·∇φᵢ)(ĝ·∇φⱼ)) with ĝ = ∇u/|∇u|: stiffness dH/dB along the
//! field and ν across it. Both are positive for a rising H(B), so every Newton system is
//! symmetric positive definite and goes to the same Cholesky as a linear one.

use super::cholesky::Analysis;
use super::coefficients::TriangleCoefficients;
use super::dofs::Numbering;
use super::element::Element;
use super::error::SolveError;
use super::problem::Problem;
use serde::{Deserialize, Serialize};

/// Newton stops once ‖R‖₂ is at most this fraction of the residual of u = 0 inside (the
/// problem's own scale: its loads, magnets and boundary values).
pub const NEWTON_TOLERANCE: f64 = 1e-10;

/// Newton gives up after this many iterations (the solve then did not converge).
pub const MAX_NEWTON_ITERATIONS: u32 = 50;

/// Halvings of a Newton step before the line search takes the smallest.
const MAX_HALVINGS: u32 = 20;

/// What Newton's method did on one mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Newton {
    /// Newton steps taken.
    pub iterations: u32,
    /// ‖R‖₂ / ‖R(u = 0 inside)‖₂ at the end.
    pub residual: f64,
    /// Whether that met [`NEWTON_TOLERANCE`].
    pub converged: bool,
    /// The relative residual before each step and at the end.
    #[serde(skip)]
    pub residuals: Vec<f64>,
}

/// The discrete problem on one mesh.
pub(super) struct System<'s, 'p> {
    pub problem: &'s Problem<'p>,
    pub triangles: &'s [[u32; 3]],
    pub elements: &'s [Element],
    pub coefficients: &'s [TriangleCoefficients],
    /// The unknown index of each vertex, `None` on a Dirichlet side.
    pub unknown: &'s [Option<usize>],
    /// u at each vertex = sign · its unknown (−1 across an antiperiodic pair).
    pub sign: &'s [f64],
    /// How many unknowns there are.
    pub unknowns: usize,
    /// The edges on open sides, with their Robin terms ([`open_edges`]).
    pub open: Vec<OpenEdge>,
}

impl<'s, 'p> System<'s, 'p> {
    /// The system of `problem` on `triangles`, their elements and coefficients, with the
    /// unknowns `numbering` gives, and the Robin terms of its open sides' edges.
    pub fn new(
        problem: &'s Problem<'p>,
        triangles: &'s [[u32; 3]],
        elements: &'s [Element],
        coefficients: &'s [TriangleCoefficients],
        numbering: &'s Numbering,
    ) -> Self {
        Self {
            problem,
            triangles,
            elements,
            coefficients,
            unknown: &numbering.unknown,
            sign: &numbering.sign,
            unknowns: numbering.masters.len(),
            open: open_edges(problem, triangles, elements, coefficients),
        }
    }
}

/// An edge on an open side: its ends, k ∫ c φₐ φ_b and k ∫ h φₐ over it (times r
/// axisymmetric), which the weak form adds for k ∂u/∂n = k (h − c u).
pub(super) struct OpenEdge {
    ends: [u32; 2],
    matrix: [[f64; 2]; 2],
    load: [f64; 2],
}

/// The edges of `triangles` that lie on an open side of `problem`, each with its Robin terms
/// by the 2-point Gauss rule, for the net source ∫ f the loads give.
fn open_edges(
    problem: &Problem<'_>,
    triangles: &[[u32; 3]],
    elements: &[Element],
    coefficients: &[TriangleCoefficients],
) -> Vec<OpenEdge> {
    if !problem.boundary().has_open() {
        return Vec::new();
    }
    // Σ_T weight · Σᵢ ∫ f φᵢ / weight = ∫ f, the hat functions summing to 1.
    let net: f64 =
        (elements.iter().zip(coefficients)).map(|(e, c)| e.weight() * c.load.iter().sum::<f64>()).sum();
    let axisymmetric = problem.geometry() == crate::result::Geometry::Axisymmetric;
    let gauss = [0.5 - 0.5 / 3f64.sqrt(), 0.5 + 0.5 / 3f64.sqrt()];
    let mut edges = Vec::new();
    for ((e, c), &tri) in elements.iter().zip(coefficients).zip(triangles) {
        for i in 0..3 {
            let (a, b) = (e.p[i], e.p[(i + 1) % 3]);
            let Some(n) = problem.open_normal(a, b) else { continue };
            let half = 0.5 * (b.x - a.x).hypot(b.y - a.y);
            let mut edge =
                OpenEdge { ends: [tri[i], tri[(i + 1) % 3]], matrix: [[0.0; 2]; 2], load: [0.0; 2] };
            for s in gauss {
                let x = crate::geom::Point::new(a.x + s * (b.x - a.x), a.y + s * (b.y - a.y));
                let (robin, data) = problem.open(x, n, net, c.k);
                let w = half * c.k * if axisymmetric { x.x } else { 1.0 };
                let phi = [1.0 - s, s];
                for alpha in 0..2 {
                    edge.load[alpha] += w * data * phi[alpha];
                    for beta in 0..2 {
                        edge.matrix[alpha][beta] += w * robin * phi[alpha] * phi[beta];
                    }
                }
            }
            edges.push(edge);
        }
    }
    edges
}

impl System<'_, '_> {
    /// Solves the linear system for the unknowns of `u`, whose Dirichlet values are set.
    pub fn linear(&self, u: &mut [f64]) -> Result<(), SolveError> {
        let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(6 * self.triangles.len());
        let mut rhs = vec![0.0; self.unknowns];
        for ((e, c), &tri) in self.elements.iter().zip(self.coefficients).zip(self.triangles) {
            let weight = e.weight();
            for i in 0..3 {
                let Some(row) = self.unknown[tri[i] as usize] else { continue };
                let si = self.sign[tri[i] as usize];
                rhs[row] += si * weight * c.load[i];
                if c.source != [0.0; 2] {
                    rhs[row] += si * weight * (c.source[0] * e.d[i][1] - c.source[1] * e.d[i][0]);
                }
                for j in 0..3 {
                    let a = c.k * weight * (e.d[i][0] * e.d[j][0] + e.d[i][1] * e.d[j][1]);
                    match self.unknown[tri[j] as usize] {
                        // Lower triangle only, stored as (column, row).
                        Some(col) if row >= col => {
                            entries.push((col, row, si * self.sign[tri[j] as usize] * a))
                        }
                        Some(_) => {}
                        None => rhs[row] -= si * a * u[tri[j] as usize],
                    }
                }
            }
        }
        for edge in &self.open {
            for alpha in 0..2 {
                let Some(row) = self.unknown[edge.ends[alpha] as usize] else { continue };
                let si = self.sign[edge.ends[alpha] as usize];
                rhs[row] += si * edge.load[alpha];
                for beta in 0..2 {
                    let (vj, a) = (edge.ends[beta] as usize, edge.matrix[alpha][beta]);
                    match self.unknown[vj] {
                        Some(col) if row >= col => entries.push((col, row, si * self.sign[vj] * a)),
                        Some(_) => {}
                        None => rhs[row] -= si * a * u[vj],
                    }
                }
            }
        }
        let x = solve_spd(self.unknowns, entries, rhs)?;
        self.scatter(&x, u, |_, x| x);
        Ok(())
    }

    /// Newton's method from `u` (Dirichlet values set, the unknowns a first guess), with a
    /// backtracking line search on ‖R‖₂.
    pub fn newton(&self, u: &mut [f64]) -> Result<Newton, SolveError> {
        let mut zero = u.to_vec();
        self.scatter(&vec![0.0; self.unknowns], &mut zero, |_, x| x);
        let scale = norm(&self.residual(&zero, None));
        if scale == 0.0 {
            // No load, magnet or boundary value: u = 0 inside is the solution.
            u.copy_from_slice(&zero);
            return Ok(Newton { iterations: 0, residual: 0.0, converged: true, residuals: vec![0.0] });
        }
        let mut entries = Vec::with_capacity(6 * self.triangles.len());
        let mut r = self.residual(u, Some(&mut entries));
        let mut relative = norm(&r) / scale;
        let mut residuals = vec![relative];
        let mut iterations = 0;
        let mut trial = u.to_vec();
        let mut analysis = None;
        while relative > NEWTON_TOLERANCE && iterations < MAX_NEWTON_ITERATIONS {
            for v in &mut r {
                *v = -*v;
            }
            // Every iteration assembles the same pattern in the same order: analyse it once.
            let analysis = match &analysis {
                Some(analysis) => analysis,
                None => analysis.insert(Analysis::new(self.unknowns, &entries)?),
            };
            let step = analysis.solve(std::mem::take(&mut entries), std::mem::take(&mut r))?;
            // Armijo's rule on ‖R‖₂; past the last halving the step is taken if R stays finite.
            // Each trial assembles its Jacobian too: the step taken is then ready for the next
            // iteration, where a second pass over the elements would compute the same bits.
            let mut alpha = 1.0;
            let mut halvings = 0;
            let accepted = loop {
                trial.copy_from_slice(u);
                self.scatter(&step, &mut trial, |u, d| u + alpha * d);
                r = self.residual(&trial, Some(&mut entries));
                let tried = norm(&r) / scale;
                if tried <= (1.0 - 1e-4 * alpha) * relative {
                    break true;
                }
                if halvings == MAX_HALVINGS {
                    break tried.is_finite();
                }
                alpha *= 0.5;
                halvings += 1;
            };
            if !accepted {
                break;
            }
            u.copy_from_slice(&trial);
            iterations += 1;
            relative = norm(&r) / scale;
            residuals.push(relative);
        }
        Ok(Newton { iterations, residual: relative, converged: relative <= NEWTON_TOLERANCE, residuals })
    }

    /// Writes `f(u, ±x)` into the vertices of `u` off the Dirichlet sides, x by unknown index
    /// and signed as the vertex takes it.
    pub fn scatter(&self, x: &[f64], u: &mut [f64], f: impl Fn(f64, f64) -> f64) {
        for ((u, index), sign) in u.iter_mut().zip(self.unknown).zip(self.sign) {
            if let Some(i) = index {
                *u = f(*u, sign * x[*i]);
            }
        }
    }

    /// R(u) by unknown index and, when `jacobian` is given, the lower triangle of its
    /// Jacobian (column, row, value) written there.
    pub fn residual(&self, u: &[f64], mut jacobian: Option<&mut Vec<(usize, usize, f64)>>) -> Vec<f64> {
        let mut r = vec![0.0; self.unknowns];
        if let Some(j) = jacobian.as_deref_mut() {
            j.clear();
        }
        for ((e, c), &tri) in self.elements.iter().zip(self.coefficients).zip(self.triangles) {
            let (g, weight) = (e.field(tri.map(|v| u[v as usize])), e.weight());
            let b = g[0].hypot(g[1]);
            let (nu, dh) = c.nu(self.problem, b);
            let q = [nu * g[0] + c.source[1], nu * g[1] - c.source[0]];
            // The extra stiffness along the field, over |∇u|².
            let along = if c.curve.is_some() && b > 0.0 { (dh - nu) / (b * b) } else { 0.0 };
            for i in 0..3 {
                let Some(row) = self.unknown[tri[i] as usize] else { continue };
                let (gi, si) = (e.d[i], self.sign[tri[i] as usize]);
                r[row] += si * weight * (q[0] * gi[0] + q[1] * gi[1] - c.load[i]);
                let Some(jac) = jacobian.as_deref_mut() else { continue };
                for (&vj, gj) in tri.iter().zip(e.d) {
                    let Some(col) = self.unknown[vj as usize] else { continue };
                    if row < col {
                        continue;
                    }
                    let mut a = nu * (gi[0] * gj[0] + gi[1] * gj[1]);
                    if along != 0.0 {
                        a += along * (g[0] * gi[0] + g[1] * gi[1]) * (g[0] * gj[0] + g[1] * gj[1]);
                    }
                    jac.push((col, row, si * self.sign[vj as usize] * weight * a));
                }
            }
        }
        for edge in &self.open {
            for alpha in 0..2 {
                let Some(row) = self.unknown[edge.ends[alpha] as usize] else { continue };
                let si = self.sign[edge.ends[alpha] as usize];
                let m = edge.matrix[alpha];
                let [ua, ub] = edge.ends.map(|v| u[v as usize]);
                r[row] += si * (m[0] * ua + m[1] * ub - edge.load[alpha]);
                let Some(jac) = jacobian.as_deref_mut() else { continue };
                for (&vj, a) in edge.ends.iter().zip(m) {
                    let vj = vj as usize;
                    if let Some(col) = self.unknown[vj]
                        && row >= col
                    {
                        jac.push((col, row, si * self.sign[vj] * a));
                    }
                }
            }
        }
        r
    }
}

/// The Euclidean norm, summed in index order.
fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Solves A x = b for the symmetric positive definite A given by its lower-triangle
/// `entries` (column, row, value); duplicates are summed.
fn solve_spd(n: usize, entries: Vec<(usize, usize, f64)>, b: Vec<f64>) -> Result<Vec<f64>, SolveError> {
    if n == 0 {
        return Ok(b);
    }
    Analysis::new(n, &entries)?.solve(entries, b)
}
