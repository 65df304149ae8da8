//! The adaptive loop of the paper's section 5: solve, rank, divide the worst segments, solve
//! again.
//!
//! Each round solves on the current mesh, writes u_h into the vertices' z, measures the
//! estimate, and then lets the refinement engine bisect worst first until the vertex count
//! has grown by `growth` (one solve per vertex would cost O(N²)). The engine is the one that
//! builds meshes ([`crate::refine`]), with u_h interpolated as the values of new vertices and
//! [`Floors::Resolution`]: a singular point gets vertices as close as floating point resolves.
//! The loop always ends on a solve, so the mesh it returns carries the solution.

use super::circuits;
use super::coefficients::TriangleCoefficients;
use super::element::Element;
use super::error::SolveError;
use super::periodic;
use super::problem::Problem;
use super::regions;
use super::residual::Residual;
use super::solution::{ErrorNorms, solve_with};
use crate::geom::Mesh;
use crate::refine::{Criterion, Floors, Method, Observer, Params, Progress, StopReason, resume, variation};
use crate::result::{Geometry, SolveStats, Step, Stop};
use serde::{Deserialize, Serialize};
use std::time::{Duration, Instant};

/// How the loop ranks where to refine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Indicator {
    /// The paper's: the edge with the largest |uᵢ − uⱼ| of the computed solution.
    Variation,
    /// The residual estimator η_T² = h_T² ‖f‖²_T + ½ Σ_E h_E ‖[k ∂u/∂n]‖²_E: the edge at the end
    /// of the worst triangle's longest-edge path is bisected (`semi-recursive` then flips).
    #[default]
    Residual,
}

/// What the loop is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Stop once the mesh has this many vertices (after solving on it).
    pub max_vertices: usize,
    /// Stop once the estimate is at most this: √Σ η_T² for `residual`, max |uᵢ − uⱼ| for
    /// `variation`.
    pub tolerance: Option<f64>,
    /// Whether the mesh stays Delaunay (`semi-recursive`) or nested (`recursive`).
    pub method: Method,
    /// The ranking.
    pub indicator: Indicator,
    /// The factor by which each round grows the vertex count (> 1).
    pub growth: f64,
    /// Stop refining once this has passed (the last mesh is still solved).
    pub time_limit: Option<Duration>,
}

/// The vertex count the loop starts from: S₄ bisected uniformly, so that f has interior
/// vertices to act on before the first solve.
pub const INITIAL_VERTICES: usize = 25;

impl Settings {
    /// Residual, semi-recursive, growth 1.5, no tolerance or time limit.
    pub fn new(max_vertices: usize) -> Self {
        Self {
            max_vertices,
            tolerance: None,
            method: Method::SemiRecursive,
            indicator: Indicator::Residual,
            growth: 1.5,
            time_limit: None,
        }
    }
}

/// A finished loop.
#[derive(Debug, Clone)]
pub struct Adapted {
    /// The final mesh, z = u_h. After a cancellation, the last solution interpolated onto
    /// the vertices the interrupted round added.
    pub mesh: Mesh,
    /// η_T of each triangle of the final mesh (`residual` only).
    pub indicators: Option<Vec<f64>>,
    /// What happened.
    pub stats: SolveStats,
    /// Per triangle of the final mesh: the flux q = k∇u + (s_y, −s_x) that the weak form tests
    /// (H rotated by −90° in magnetostatics: H = (q_y, −q_x)) and k there (ν(|B|) on a curve).
    pub fields: Vec<[f64; 3]>,
    /// Time from the start to the end of each solve, in step order: the one thing that
    /// differs between identical runs, so kept out of the stats.
    pub times: Vec<Duration>,
    /// How the problem read the plane.
    pub geometry: Geometry,
    /// Per triangle of the final mesh: the index of the topmost region holding its centroid,
    /// −1 for none (empty when the problem has no regions).
    pub region_of: Vec<i32>,
}

/// An exact solution to measure u_h against.
pub type Exact<'e> = &'e (dyn Fn(f64, f64) -> f64 + Sync);

/// Runs the adaptive loop. `observer` hears one [`Progress`] per solve (`worst` is the
/// estimate), may cancel between steps, and sees every insertion.
///
/// # Errors
/// The first [`SolveError`] of a solve or of the indicator's sampling of k and f.
pub fn adapt<O: SolveObserver>(
    problem: &Problem<'_>,
    exact: Option<Exact<'_>>,
    settings: &Settings,
    observer: &mut O,
) -> Result<Adapted, SolveError> {
    let start = Instant::now();
    let mut mesh = if problem.regions().is_empty() {
        Mesh::with_capacity(problem.domain(), [0.0; 4], settings.max_vertices)
    } else {
        Mesh::constrained(problem.domain(), &problem.sides(), settings.max_vertices)?
    };
    let mut residual = Residual::new(problem);
    let mut forward = Forward(observer);
    // Every z is 0, so every edge ties and the engine splits longest first: a uniform start.
    let initial =
        round_params(INITIAL_VERTICES.min(settings.max_vertices), Criterion::Variation, settings, None);
    resume(&mut mesh, &mut residual, &initial, Floors::Resolution, &mut forward)?;
    if settings.indicator == Indicator::Residual {
        residual.measure_all(&mesh)?;
    }
    let mut run = Finish {
        problem,
        flips: 0,
        retired: 0,
        unknowns: 0,
        coenergy: 0.0,
        history: Vec::new(),
        times: Vec::new(),
    };
    let mut pending = None;
    loop {
        let matched = periodic::match_sides(&mut mesh, problem, settings.method)?;
        if matched && settings.indicator == Indicator::Residual {
            residual.measure_all(&mesh)?;
        }
        let triangles: Vec<[u32; 3]> = mesh.triangles().collect();
        let known = (settings.indicator == Indicator::Residual).then(|| residual.coefficients());
        // Newton starts from the last solution, interpolated onto the vertices since added.
        let guess: Option<Vec<f64>> =
            problem.is_nonlinear().then(|| mesh.vertices().iter().map(|v| v.z).collect());
        let solution = solve_with(problem, mesh.vertices(), &triangles, known, guess.as_deref())?;
        let converged = solution.newton.as_ref().is_none_or(|n| n.converged);
        if !converged && !run.history.is_empty() {
            // The mesh keeps the last converged solution, interpolated.
            return run.finish(mesh, &residual, settings.indicator, Stop::NotConverged);
        }
        mesh.set_values(&solution.u);
        let estimate = match settings.indicator {
            Indicator::Variation => variation(&mesh),
            Indicator::Residual => {
                residual.solved(&solution.gradients);
                total(&residual, &mesh)
            }
        };
        let norms = match exact {
            Some(u) => {
                Some(solution.errors(problem, mesh.vertices(), &triangles, u, |x, y| gradient(u, x, y))?)
            }
            None => None,
        };
        let n = mesh.num_vertices();
        run.unknowns = solution.num_unknowns;
        run.coenergy = solution.coenergy;
        run.history.push(Step {
            vertices: n,
            estimate,
            energy: solution.energy,
            max_nodal_error: norms.map(|n: ErrorNorms| n.max_nodal),
            l2_error: norms.map(|n| n.l2),
            energy_error: norms.map(|n| n.energy),
            newton_iterations: solution.newton.as_ref().map(|n| n.iterations),
            newton_residual: solution.newton.as_ref().map(|n| n.residual),
        });
        // Time paused for another job's turn is not the solve's.
        let elapsed = start.elapsed().saturating_sub(forward.0.paused());
        run.times.push(elapsed);
        let progress = Progress { vertices: n, triangles: mesh.num_triangles(), worst: estimate, elapsed };
        forward.0.solved(&mesh, &progress, solution.newton.as_ref().map(|n| (n.iterations, n.residual)));

        let remaining = settings.time_limit.map(|limit| limit.saturating_sub(elapsed));
        let stop = (!converged).then_some(Stop::NotConverged).or(pending
            .or_else(|| settings.tolerance.is_some_and(|t| estimate <= t).then_some(StopReason::Tolerance))
            .or_else(|| (n >= settings.max_vertices).then_some(StopReason::MaxVertices))
            .or_else(|| (remaining == Some(Duration::ZERO)).then_some(StopReason::TimeLimit))
            .map(Stop::Mesh));
        if let Some(stop) = stop {
            return run.finish(mesh, &residual, settings.indicator, stop);
        }
        let target = ((n as f64 * settings.growth).ceil() as usize).clamp(n + 1, settings.max_vertices);
        let criterion = match settings.indicator {
            Indicator::Variation => Criterion::Variation,
            Indicator::Residual => Criterion::Error,
        };
        let params = round_params(target, criterion, settings, remaining);
        let round = resume(&mut mesh, &mut residual, &params, Floors::Resolution, &mut forward)?;
        run.flips += round.flips;
        run.retired += round.retired;
        match round.stop {
            StopReason::MaxVertices => {}
            // Nothing to solve again: the mesh is the one just solved, or the job is over.
            StopReason::Cancelled => {
                return run.finish(mesh, &residual, settings.indicator, Stop::Mesh(round.stop));
            }
            StopReason::Exhausted if mesh.num_vertices() == n => {
                return run.finish(mesh, &residual, settings.indicator, Stop::Mesh(round.stop));
            }
            // Solve what the round made, then stop.
            other => pending = Some(other),
        }
    }
}

/// √Σ η_T² over the mesh.
fn total(residual: &Residual<'_, '_>, mesh: &Mesh) -> f64 {
    let mut sum = 0.0;
    for t in 0..mesh.num_triangles() as u32 {
        sum += residual.indicator_sq(mesh, t);
    }
    sum.sqrt()
}

/// What the loop has gathered so far.
struct Finish<'p, 'a> {
    problem: &'p Problem<'a>,
    flips: u64,
    retired: u64,
    unknowns: usize,
    coenergy: f64,
    history: Vec<Step>,
    times: Vec<Duration>,
}

impl Finish<'_, '_> {
    fn finish(
        self,
        mesh: Mesh,
        residual: &Residual<'_, '_>,
        indicator: Indicator,
        stop: Stop,
    ) -> Result<Adapted, SolveError> {
        let last = *self.history.last().expect("the loop solves before it stops");
        let indicators = match indicator {
            Indicator::Variation => None,
            Indicator::Residual => Some(
                (0..mesh.num_triangles() as u32).map(|t| residual.indicator_sq(&mesh, t).sqrt()).collect(),
            ),
        };
        let stats = SolveStats {
            vertices: mesh.num_vertices(),
            triangles: mesh.num_triangles(),
            unknowns: self.unknowns,
            solves: self.history.len(),
            estimate: last.estimate,
            energy: last.energy,
            coenergy: self.coenergy,
            flips: self.flips,
            retired_edges: self.retired,
            stop,
            delaunay: mesh.is_delaunay(),
            constrained_edges: mesh.num_constrained(),
            regions: Vec::new(),
            circuits: Default::default(),
            history: self.history,
        };
        let geometry = self.problem.geometry();
        let mut adapted = Adapted {
            mesh,
            indicators,
            stats,
            fields: Vec::new(),
            times: self.times,
            geometry,
            region_of: Vec::new(),
        };
        measure_fields(self.problem, &mut adapted, residual, indicator)?;
        Ok(adapted)
    }
}

/// Each triangle's flux, coefficient and region, and each region's figures, on the final
/// mesh from the values it carries.
///
/// # Errors
/// A triangle the last round added but no solve sampled (a cancelled or stopped round) whose
/// k or f is invalid: [`TriangleCoefficients::of`]'s error.
fn measure_fields(
    problem: &Problem<'_>,
    adapted: &mut Adapted,
    residual: &Residual<'_, '_>,
    indicator: Indicator,
) -> Result<(), SolveError> {
    let mesh = &adapted.mesh;
    let points: Vec<_> = mesh.vertices().iter().map(|v| v.point()).collect();
    let u: Vec<f64> = mesh.vertices().iter().map(|v| v.z).collect();
    let triangles: Vec<[u32; 3]> = mesh.triangles().collect();
    let elements = (triangles.iter().enumerate())
        .map(|(t, &tri)| Element::in_geometry(problem.geometry(), &points, tri, t))
        .collect::<Result<Vec<_>, _>>()?;
    let gradients: Vec<[f64; 2]> =
        (elements.iter().zip(&triangles)).map(|(e, tri)| e.field(tri.map(|v| u[v as usize]))).collect();
    let mut measured = Vec::new();
    if indicator == Indicator::Variation {
        for (t, e) in elements.iter().enumerate() {
            measured.push(TriangleCoefficients::of(problem, e, t)?);
        }
    }
    let coefficients = match indicator {
        Indicator::Residual => residual.coefficients(),
        Indicator::Variation => &measured,
    };
    adapted.fields = (gradients.iter().zip(coefficients))
        .map(|(&g, c)| {
            let q = c.flux(problem, g);
            [q[0], q[1], c.nu(problem, g[0].hypot(g[1])).0]
        })
        .collect();
    if !problem.regions().is_empty() {
        adapted.region_of = (elements.iter())
            .map(|e| {
                let centre = e.point(&[1.0 / 3.0; 3]);
                problem.regions().iter().rposition(|r| r.contains(centre)).map_or(-1, |i| i as i32)
            })
            .collect();
    }
    adapted.stats.regions =
        regions::measure(problem, &points, &u, &triangles, &elements, &gradients, coefficients);
    adapted.stats.circuits = circuits::measure(problem, &points, &u, &triangles, &elements, coefficients)?;
    Ok(())
}

/// The engine's parameters for one round.
fn round_params(
    target: usize,
    criterion: Criterion,
    settings: &Settings,
    time_limit: Option<Duration>,
) -> Params {
    let params = Params::builder(target.max(4)).criterion(criterion).method(settings.method);
    let params = match time_limit {
        Some(t) => params.time_limit(t),
        None => params,
    };
    // A solution's methods are recursive or semi-recursive, and it sets no min_angle.
    params.build().expect("a round's target is a valid budget")
}

/// Watches an adaptive solve: the mesher's hooks, and one report per solve. The mesher's own
/// progress reports do not reach it: the loop reports once per solve.
pub trait SolveObserver: Observer {
    /// A solve on `mesh` ended: `progress` as a mesh reports it, with the estimate as its
    /// worst value, and Newton's steps and final relative residual for a nonlinear problem.
    fn solved(&mut self, mesh: &Mesh, progress: &Progress, _newton: Option<(u32, f64)>) {
        self.progress(mesh, progress);
    }
}

impl SolveObserver for () {}

/// Passes cancellation and insertions through to the loop's observer, but not the engine's
/// progress reports: the loop reports once per solve.
struct Forward<'o, O>(&'o mut O);

impl<O: SolveObserver> Observer for Forward<'_, O> {
    fn is_cancelled(&self) -> bool {
        self.0.is_cancelled()
    }

    fn paused(&self) -> Duration {
        self.0.paused()
    }

    fn inserted(&mut self, mesh: &Mesh, vertex: u32) {
        self.0.inserted(mesh, vertex);
    }
}

/// ∇u at (x, y) by central differences, with a step that scales with the point's magnitude
/// (about ε^⅓ of it, the step that balances truncation against rounding), so that the
/// gradient is resolved near a singular point at the origin as well as far from it.
fn gradient(u: Exact<'_>, x: f64, y: f64) -> [f64; 2] {
    let h = 6e-6 * x.abs().max(y.abs()).max(1e-200);
    // Divided by the rounded steps actually taken, not by 2h.
    let (xp, xm, yp, ym) = (x + h, x - h, y + h, y - h);
    [(u(xp, y) - u(xm, y)) / (xp - xm), (u(x, yp) - u(x, ym)) / (yp - ym)]
}

#[cfg(test)]
mod circuit_tests;
#[cfg(test)]
mod physics_tests;
#[cfg(test)]
mod tests;
