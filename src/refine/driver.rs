//! The engine's two entry points: [`refine`] a surface from S₄, and [`resume`] a mesh as it
//! stands with values that change between rounds.

use super::angles;
use super::curvature_criterion;
use super::error_criterion;
use super::estimator::Estimator;
use super::floors::Floors;
use super::history::History;
use super::nodes;
use super::observer::Observer;
use super::outcome::{RefineError, Refinement, Stats};
use super::params::{Criterion, Method, Params};
use super::run::{Round, Run};
use super::sampler::{Batch, Sampler};
use super::variation_criterion;
use crate::geom::{Mesh, Rect};
use crate::source::Surface;
use std::time::{Duration, Instant};

/// Refines S₄ on `rect` until a stop rule of `params` fires. See the [module docs](crate::refine).
///
/// # Errors
/// [`RefineError::NonFinite`] when F is not finite at a corner or at a point the refinement
/// needs (a midpoint to insert, or a sample of the error criterion).
pub fn refine<S, O>(
    surface: &S,
    rect: Rect,
    params: &Params,
    observer: &mut O,
) -> Result<Refinement, RefineError>
where
    S: Surface + ?Sized,
    O: Observer,
{
    let (start, paused_before) = (Instant::now(), observer.paused());
    let mut sampler = Sampler { surface, evaluations: 0, batch: Batch::default() };
    let [p1, p2, p3, p4] = rect.corners();
    let z = [sampler.eval(p1)?, sampler.eval(p2)?, sampler.eval(p3)?, sampler.eval(p4)?];
    let mut mesh = Mesh::with_capacity(rect, z, params.max_vertices());
    let floors = Floors::of_rect(rect);
    let round = match surface.grid() {
        Some(grid) if params.criterion() == Criterion::Error && params.method() != Method::Recursive => {
            let mut run = Run::new(params, observer, floors);
            let (stop, errors) =
                nodes::refine(&mut mesh, grid, &mut run, &mut sampler.evaluations, false, None);
            run.finish(&mesh, stop, Some(errors))
        }
        _ => resume(&mut mesh, &mut sampler, params, floors, observer)?,
    };
    // Time paused for another job's turn is not the refinement's.
    let paused = observer.paused().saturating_sub(paused_before);
    Ok(finished(mesh, round, params, sampler.evaluations, start, paused))
}

/// The refinement `round` made of `mesh`, with its stats.
pub(super) fn finished(
    mesh: Mesh,
    round: Round,
    params: &Params,
    evaluations: u64,
    start: Instant,
    paused: Duration,
) -> Refinement {
    let max_triangle_error =
        round.triangle_errors.as_ref().map(|e: &Vec<f64>| e.iter().copied().fold(0.0, f64::max));
    let stats = Stats {
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        // The history's final sample walked the final mesh (or knew V_n): not again here.
        variation: History::final_variation(&round.history),
        max_triangle_error,
        flips: round.flips,
        retired_edges: round.retired,
        evaluations,
        stop: round.stop,
        delaunay: mesh.is_delaunay(),
        below_min_angle: params.min_angle().map(|degrees| angles::count_below(&mesh, degrees)),
        history: round.history,
        quality: None,
    };
    Refinement {
        mesh,
        triangle_errors: round.triangle_errors,
        stats,
        elapsed: start.elapsed().saturating_sub(paused),
    }
}

/// Refines `mesh` as it stands until a stop rule of `params` fires (the time limit counts
/// from this call): the loop of [`refine`], open to values that change between rounds. New
/// vertices take their z from `estimator` as a [`Field`]; criterion `error` ranks triangles by
/// its estimates, `variation` by the vertices' z.
pub(crate) fn resume<E: Estimator, O: Observer>(
    mesh: &mut Mesh,
    estimator: &mut E,
    params: &Params,
    floors: Floors,
    observer: &mut O,
) -> Result<Round, E::Error> {
    let mut run = Run::new(params, observer, floors);
    let (stop, triangle_errors) = match params.criterion() {
        Criterion::Variation => (variation_criterion::refine(mesh, estimator, &mut run)?, None),
        Criterion::Curvature => (curvature_criterion::refine(mesh, estimator, &mut run)?, None),
        Criterion::Error => {
            let (stop, errors) = error_criterion::refine(mesh, estimator, &mut run)?;
            (stop, Some(errors))
        }
    };
    Ok(run.finish(mesh, stop, triangle_errors))
}
