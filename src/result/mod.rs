//! A finished job as data: the mesh's arrays and its stats.
//!
//! Everything after the engine works on this: stores keep it (in memory as is, on disk in the
//! checksummed form of [`compact`]), and `output` encodes it in the format a client asks for.
//! Nothing in it depends on the machine or the moment: the same request gives the same
//! result, bit for bit.

pub mod compact;
pub mod locate;

use crate::geom::Vertex;
use crate::refine::trace::Trace;
use crate::refine::{Refinement, Stats, StopReason};
use crate::solve::{Adapted, Element, MU_0, Physics, SolveStats};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// A refined mesh: vertices in insertion order (any prefix is an earlier step's vertex set),
/// counter-clockwise triangles, and what is known per triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshResult {
    /// x, y and F(x, y), in insertion order; the first four are the rectangle's corners.
    pub vertices: Vec<Vertex>,
    /// Vertex ids of each triangle, counter-clockwise.
    pub triangles: Vec<[u32; 3]>,
    /// e(T) of each triangle (criterion `error` only), or a solution's indicator η_T.
    pub triangle_errors: Option<Vec<f64>>,
    /// The run's counters and outcome.
    pub stats: Summary,
    /// What each step of the run did, so that smaller requests are answered from it (none
    /// for a result that was itself replayed from another).
    pub trace: Option<Arc<Trace>>,
    /// A magnetostatic solution's field strength and permeability per triangle: [Hx, Hy, μr]
    /// (A/m; μr = 1/(μ0 ν), the secant permeability B/(μ0 H) on a B–H curve).
    pub magnetic_field: Option<Vec<[f64; 3]>>,
}

impl From<Refinement> for MeshResult {
    fn from(r: Refinement) -> Self {
        Self {
            vertices: r.mesh.vertices().to_vec(),
            triangles: r.mesh.triangles().collect(),
            triangle_errors: r.triangle_errors,
            stats: Summary::Mesh(r.stats),
            trace: None,
            magnetic_field: None,
        }
    }
}

/// What a result's run reports: a mesh's stats or a solution's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Summary {
    /// A mesh of F.
    Mesh(Stats),
    /// The solution of a boundary value problem.
    Solution(SolutionStats),
}

/// A solution's stats with what u stands for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolutionStats {
    /// What u stands for.
    pub physics: Physics,
    /// The adaptive loop's counters, estimate, energy and history.
    #[serde(flatten)]
    pub run: SolveStats,
}

impl Summary {
    /// Why the run stopped.
    pub fn stop(&self) -> StopReason {
        match self {
            Summary::Mesh(s) => s.stop,
            Summary::Solution(s) => s.run.stop,
        }
    }

    /// What u stands for, for a solution.
    pub fn physics(&self) -> Option<Physics> {
        match self {
            Summary::Mesh(_) => None,
            Summary::Solution(s) => Some(s.physics),
        }
    }
}

impl MeshResult {
    /// The result of an adaptive solve: z = u at every vertex, η_T per triangle.
    pub fn solution(adapted: Adapted, physics: Physics) -> Self {
        Self {
            vertices: adapted.mesh.vertices().to_vec(),
            triangles: adapted.mesh.triangles().collect(),
            triangle_errors: adapted.indicators,
            stats: Summary::Solution(SolutionStats { physics, run: adapted.stats }),
            trace: None,
            // H = (q_y, −q_x) from the flux q the weak form tests.
            magnetic_field: (physics == Physics::Magnetostatic)
                .then(|| adapted.fields.iter().map(|&[qx, qy, k]| [qy, -qx, 1.0 / (MU_0 * k)]).collect()),
        }
    }

    /// For a magnetostatic solution, B = (∂A/∂y, −∂A/∂x) on every triangle, in tesla.
    pub fn flux_density(&self) -> Option<Vec<[f64; 2]>> {
        if self.stats.physics() != Some(Physics::Magnetostatic) {
            return None;
        }
        let b = self.triangles.iter().enumerate().map(|(t, &tri)| {
            let z = tri.map(|v| self.vertices[v as usize].z);
            // A stored result's triangles are counter-clockwise, so this never fails.
            let g = Element::new(&self.vertices, tri, t).map_or([0.0; 2], |e| e.gradient(z));
            [g[1], -g[0]]
        });
        Some(b.collect())
    }
}

impl MeshResult {
    /// Bytes the arrays take in memory: what a cache weighs it by.
    pub fn num_bytes(&self) -> usize {
        let errors = self.triangle_errors.as_ref().map_or(0, Vec::len);
        size_of::<Self>()
            + self.vertices.len() * size_of::<Vertex>()
            + self.triangles.len() * size_of::<[u32; 3]>()
            + errors * size_of::<f64>()
            + self.magnetic_field.as_ref().map_or(0, |h| h.len() * size_of::<[f64; 3]>())
            + self.trace.as_ref().map_or(0, |t| t.num_bytes())
    }

    /// The smallest and largest z, or (0, 0) for no vertices.
    pub fn z_range(&self) -> (f64, f64) {
        let mut zs = self.vertices.iter().map(|v| v.z);
        let first = zs.next().unwrap_or(0.0);
        zs.fold((first, first), |(lo, hi), z| (lo.min(z), hi.max(z)))
    }

    /// The rectangle [x0, x1] × [y0, y1] the vertices span.
    pub fn bounds(&self) -> [f64; 4] {
        let mut b = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
        for v in &self.vertices {
            b = [b[0].min(v.x), b[1].max(v.x), b[2].min(v.y), b[3].max(v.y)];
        }
        b
    }
}

#[cfg(test)]
pub(crate) mod testing {
    //! A small result for the tests of stores and encoders.

    use super::MeshResult;
    use crate::geom::Rect;
    use crate::refine::trace::Recorder;
    use crate::refine::{Criterion, Params, refine};
    use std::sync::Arc;

    fn bump(x: f64, y: f64) -> f64 {
        (-4.0 * ((x - 0.3).powi(2) + (y - 0.6).powi(2))).exp() - 0.25
    }

    fn rect() -> Rect {
        Rect::new(-1.0, 2.0, 0.0, 1.0).unwrap()
    }

    /// A refined mesh of a bump on [-1, 2] × [0, 1] with `n` vertices, with or without
    /// per-triangle errors.
    pub(crate) fn sample(n: usize, criterion: Criterion) -> MeshResult {
        let params = Params::new(n).unwrap().with_criterion(criterion);
        refine(&bump, rect(), &params, &mut ()).unwrap().into()
    }

    /// The magnetostatic solution around a square conductor of 1 A in a box of air on
    /// [0, 1]², on about `n` vertices.
    pub(crate) fn magnetic(n: usize) -> MeshResult {
        use crate::solve::{MU_0, Physics, Problem, Region, Settings, Shape, adapt};
        let conductor = Rect::new(0.4, 0.6, 0.4, 0.6).unwrap();
        let region = Region { f: Some(25.0), ..Region::new(Shape::Rect(conductor)) };
        let problem = Problem::new(Rect::unit()).with_k(|_, _| 1.0 / MU_0).with_region(region);
        let adapted = adapt(&problem, None, &Settings::new(n), &mut ()).unwrap();
        MeshResult::solution(adapted, Physics::Magnetostatic)
    }

    /// [`sample`] with its trace.
    pub(crate) fn traced(n: usize, criterion: Criterion) -> MeshResult {
        let params = Params::new(n).unwrap().with_criterion(criterion);
        let mut quiet = ();
        let mut recorder = Recorder::new(&mut quiet, &params);
        let run = refine(&bump, rect(), &params, &mut recorder).unwrap();
        let trace = recorder.finish(run.stats.stop).expect("a replayable method");
        MeshResult { trace: Some(Arc::new(trace)), ..run.into() }
    }
}
