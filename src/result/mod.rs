//! A finished run as data: the mesh's arrays, its named fields and its report.
//!
//! Everything after the engine works on this: stores keep it (in memory as is, on disk in the
//! checksummed form of [`compact`]), and `output` encodes it in the format a client asks for.
//! Nothing in it depends on the machine or the moment: the same request gives the same
//! result, bit for bit.
//!
//! - `finished`: [`RunResult`], vertices and triangles with their fields, stats and trace;
//! - `field`: [`Field`], a named array per vertex or per triangle, with its unit, components
//!   and role (which writers carry it);
//! - `stats`: what a run reports ([`Summary`]): a mesh's stats, or a solution's with what u
//!   stood for;
//! - [`compact`]: the checksummed binary form stores keep;
//! - [`locate`]: point location, for F_n at any point.

pub mod compact;
mod field;
mod finished;
pub mod locate;
pub mod probe;
mod stats;

pub use field::{Field, Lines, Location, Role};
pub use finished::{RunResult, triangle_errors};
pub use stats::{
    Checkpoint, CircuitStats, Geometry, MeshStats, Physics, Quality, RegionStats, SolutionStats, SolveStats,
    Step, Stop, Summary, Unit,
};

#[cfg(test)]
pub(crate) mod testing {
    //! A small result for the tests of stores and encoders.

    use super::{Geometry, RunResult};
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
    pub(crate) fn sample(n: usize, criterion: Criterion) -> RunResult {
        let params = Params::builder(n).criterion(criterion).build().unwrap();
        refine(&bump, rect(), &params, &mut ()).unwrap().into()
    }

    /// The magnetostatic solution around a square conductor of 1 A in a box of air on
    /// [0, 1]², on about `n` vertices.
    pub(crate) fn magnetic(n: usize) -> RunResult {
        use crate::solve::{MU_0, Physics, Problem, Region, Settings, Shape, adapt};
        let conductor = Rect::new(0.4, 0.6, 0.4, 0.6).unwrap();
        let region = Region { f: Some(25.0), ..Region::new(Shape::Rect(conductor)) };
        let problem = Problem::new(Rect::unit()).with_k(|_, _| 1.0 / MU_0).with_region(region);
        let adapted = adapt(&problem, None, &Settings::new(n), &mut ()).unwrap();
        adapted.into_result(Physics::Magnetostatic)
    }

    /// `result`, a magnetostatic solution, with A = `a(x, y)` at every vertex and B made anew
    /// from it.
    pub(crate) fn with_potential(mut result: RunResult, a: impl Fn(f64, f64) -> f64) -> RunResult {
        result.vertices.iter_mut().for_each(|v| v.z = a(v.x, v.y));
        let b = crate::solve::flux_density(Geometry::Planar, &result.vertices, &result.triangles);
        let at = result.fields.iter().position(|f| f.name == "B").expect("a magnetostatic solution");
        result.fields[at] = b;
        result
    }

    /// [`sample`] with its trace.
    pub(crate) fn traced(n: usize, criterion: Criterion) -> RunResult {
        let params = Params::builder(n).criterion(criterion).build().unwrap();
        let mut quiet = ();
        let mut recorder = Recorder::new(&mut quiet, &params);
        let run = refine(&bump, rect(), &params, &mut recorder).unwrap();
        let trace = recorder.finish(run.stats.stop).expect("a replayable method");
        RunResult { trace: Some(Arc::new(trace)), ..run.into() }
    }
}
