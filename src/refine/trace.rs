//! A run's trace: what each step did, enough to replay any prefix of the run without F.
//!
//! Vertices are inserted one at a time and a run never looks ahead, so a run with a smaller
//! budget, or with a tolerance the run passed, makes exactly the first steps of a larger one
//! and stops. [`Recorder`] writes down, per step, the worst criterion value it compared with
//! the tolerance, the half-edge it split (or that it retired an edge), the evaluations so
//! far, and for `error` each triangle estimate it made. [`replay`] redoes the topology steps
//! with the vertices the run already computed and stops where the smaller request would:
//! the mesh, the per-triangle errors and the stats come out bit for bit as a fresh run's.
//!
//! Cost: for `variation`, 24 bytes a step; for `error`, 24 bytes a step plus 12 bytes for
//! each estimate (about five a step).

use super::floors::Floors;
use super::history::History;
use super::observer::{Observer, Progress};
use super::outcome::{Refinement, Stats, StopReason};
use super::params::{Criterion, Method};
use super::run::{insert, place};
use crate::geom::{Mesh, NONE, Rect, Vertex};

/// What a traced run did, step by step.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// The run's method.
    pub method: Method,
    /// The run's criterion.
    pub criterion: Criterion,
    /// Whether the run put its vertices on grid nodes, not only at edge midpoints.
    pub on_nodes: bool,
    /// The run's `min_angle`, which its stats count the triangles below.
    pub min_angle: Option<f64>,
    /// Why the run stopped.
    pub stop: StopReason,
    /// Evaluations of F before the first step.
    pub base_evaluations: u64,
    /// The worst criterion value compared with the tolerance at each check; one more than
    /// `splits` when the tolerance stopped the run.
    pub worst: Vec<f64>,
    /// Per step, the half-edge split (its id before the split), or [`NONE`] for a retired edge.
    pub splits: Vec<u32>,
    /// Per step, the evaluations of F so far.
    pub evaluations: Vec<u64>,
    /// Triangle estimates in the order made (`error` only): triangle and e(T).
    pub estimates: Vec<(u32, f64)>,
    /// How many of `estimates` were made before the first step, then by the end of each step.
    pub estimate_ends: Vec<u32>,
}

impl Trace {
    /// Bytes the trace takes, for caches and the note on its cost.
    pub fn num_bytes(&self) -> usize {
        size_of::<Self>()
            + 8 * self.worst.len()
            + 4 * self.splits.len()
            + 8 * self.evaluations.len()
            + 16 * self.estimates.len()
            + 4 * self.estimate_ends.len()
    }
}

impl Trace {
    /// Whether a run of `max_vertices` and `tolerance` stops within this trace of a run that
    /// ended with `vertices` vertices, so that [`replay`] answers it: a cheap test to make
    /// before a replay, which would otherwise walk the whole trace to find it does not.
    ///
    /// Never for `data-dependent`: its last flips depend on where it stopped, so a prefix of
    /// its steps is not a smaller run's mesh.
    pub fn covers(&self, vertices: usize, max_vertices: usize, tolerance: Option<f64>) -> bool {
        if self.method == Method::DataDependent {
            return false;
        }
        max_vertices <= vertices
            || self.stop == StopReason::Exhausted
            || tolerance.is_some_and(|t| self.worst.iter().any(|&w| w <= t))
    }
}

/// An observer that traces a run and passes every report on to `inner`.
pub struct Recorder<'o, O> {
    inner: &'o mut O,
    /// `None` for a run no trace can replay (`data-dependent`, see [`Trace::covers`]): it
    /// records nothing rather than hold a trace nobody reads.
    trace: Option<Trace>,
}

impl<'o, O: Observer> Recorder<'o, O> {
    /// Traces a run of `params`, reporting to `inner` as well.
    pub fn new(inner: &'o mut O, params: &super::Params) -> Self {
        let replayable = params.method() != Method::DataDependent;
        let trace = replayable.then(|| Trace {
            method: params.method(),
            criterion: params.criterion(),
            on_nodes: false,
            min_angle: params.min_angle(),
            stop: StopReason::Exhausted,
            base_evaluations: 0,
            worst: Vec::new(),
            splits: Vec::new(),
            evaluations: Vec::new(),
            estimates: Vec::new(),
            estimate_ends: Vec::new(),
        });
        Self { inner, trace }
    }

    /// The trace of the run that ended with `stop`; `None` for a run no trace can replay.
    pub fn finish(self, stop: StopReason) -> Option<Trace> {
        self.trace.map(|trace| Trace { stop, ..trace })
    }
}

impl<O: Observer> Observer for Recorder<'_, O> {
    fn progress(&mut self, mesh: &Mesh, progress: &Progress) {
        self.inner.progress(mesh, progress);
    }

    fn is_cancelled(&self) -> bool {
        self.inner.is_cancelled()
    }

    fn paused(&self) -> std::time::Duration {
        self.inner.paused()
    }

    fn selected(&mut self, mesh: &Mesh, a: u32, b: u32) {
        self.inner.selected(mesh, a, b);
    }

    fn retired(&mut self, a: u32, b: u32) {
        self.inner.retired(a, b);
    }

    fn inserted(&mut self, mesh: &Mesh, vertex: u32) {
        self.inner.inserted(mesh, vertex);
    }

    fn on_nodes(&mut self) {
        if let Some(trace) = &mut self.trace {
            trace.on_nodes = true;
        }
        self.inner.on_nodes();
    }

    fn started(&mut self, evaluations: u64) {
        if let Some(trace) = &mut self.trace {
            trace.base_evaluations = evaluations;
            trace.estimate_ends.push(trace.estimates.len() as u32);
        }
        self.inner.started(evaluations);
    }

    fn checked(&mut self, worst: f64) {
        if let Some(trace) = &mut self.trace {
            trace.worst.push(worst);
        }
        self.inner.checked(worst);
    }

    fn estimated(&mut self, t: u32, error: f64) {
        if let Some(trace) = &mut self.trace {
            trace.estimates.push((t, error));
        }
        self.inner.estimated(t, error);
    }

    fn stepped(&mut self, split: Option<u32>, evaluations: u64) {
        if let Some(trace) = &mut self.trace {
            trace.splits.push(split.unwrap_or(NONE));
            trace.evaluations.push(evaluations);
            trace.estimate_ends.push(trace.estimates.len() as u32);
        }
        self.inner.stepped(split, evaluations);
    }
}

/// The run of `max_vertices` and `tolerance` (the traced run's other parameters) that
/// `trace` and the traced run's `vertices` already contain, as a fresh run would make it; or
/// `None` when that run would go past the traced one. Evaluates no F.
///
/// The time a replay takes is not a run's time: `elapsed` is zero. `None` for a
/// `data-dependent` run (see [`Trace::covers`]).
pub fn replay(
    trace: &Trace,
    vertices: &[Vertex],
    max_vertices: usize,
    tolerance: Option<f64>,
) -> Option<Refinement> {
    if trace.method == Method::DataDependent {
        return None;
    }
    let [p1, _, p3, _] = vertices.get(..4)?.try_into().ok()?;
    let rect = Rect::new(p1.x, p3.x, p1.y, p3.y).ok()?;
    let z = [0, 1, 2, 3].map(|k| vertices[k].z);
    let mut mesh = Mesh::with_capacity(rect, z, max_vertices.min(vertices.len()));
    let floors = Floors::of_rect(rect);
    let error = trace.criterion == Criterion::Error;
    let mut errors: Vec<f64> = Vec::new();
    let apply = |estimates: &[(u32, f64)], errors: &mut Vec<f64>| {
        for &(t, e) in estimates {
            if errors.len() <= t as usize {
                errors.resize(t as usize + 1, 0.0);
            }
            errors[t as usize] = e;
        }
    };
    let ends = &trace.estimate_ends;
    if error {
        apply(trace.estimates.get(..*ends.first()? as usize)?, &mut errors);
    }
    let (mut flips, mut retired, mut evaluations) = (0u64, 0u64, trace.base_evaluations);
    let mut stack = Vec::new();
    let mut history = History::new(trace.criterion, trace.method);
    let stop = 'steps: {
        for step in 0.. {
            if mesh.num_vertices() >= max_vertices {
                break 'steps StopReason::MaxVertices;
            }
            let Some(&worst) = trace.worst.get(step) else {
                // The traced run stopped here; only running out of edges stops any run here.
                break 'steps match trace.stop {
                    StopReason::Exhausted => StopReason::Exhausted,
                    _ => return None,
                };
            };
            history.check(&mesh, worst);
            if tolerance.is_some_and(|t| worst <= t) {
                break 'steps StopReason::Tolerance;
            }
            let &split = trace.splits.get(step)?;
            if split == NONE {
                retired += 1;
                history.retired();
            } else {
                let v = *vertices.get(mesh.num_vertices())?;
                if (split as usize) >= mesh.num_halfedges() {
                    return None;
                }
                let (a, b) = (mesh.point(mesh.origin(split)), mesh.point(mesh.dest(split)));
                // Not the trace of these vertices: never guess.
                if !trace.on_nodes && a.midpoint(b) != v.point() {
                    return None;
                }
                let placement = place(&mesh, split, v.point(), floors.at(a, b).1)?;
                flips +=
                    u64::from(insert(&mut mesh, split, v, placement, trace.method, &mut stack, |_, _| {}).1);
            }
            evaluations = *trace.evaluations.get(step)?;
            if error {
                let (from, to) = (*ends.get(step)? as usize, *ends.get(step + 1)? as usize);
                apply(trace.estimates.get(from..to)?, &mut errors);
            }
        }
        unreachable!("the loop only ends by a break")
    };
    let triangle_errors = match error {
        true => Some(errors.get(..mesh.num_triangles())?.to_vec()),
        false => None,
    };
    let history = history.finish(&mesh);
    let stats = Stats {
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        variation: History::final_variation(&history),
        max_triangle_error: triangle_errors.as_ref().map(|e| e.iter().copied().fold(0.0, f64::max)),
        flips,
        retired_edges: retired,
        evaluations,
        stop,
        delaunay: mesh.is_delaunay(),
        below_min_angle: trace.min_angle.map(|degrees| super::angles::count_below(&mesh, degrees)),
        history,
        quality: None,
    };
    Some(Refinement { mesh, triangle_errors, stats, elapsed: std::time::Duration::ZERO })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::{Params, refine};
    use crate::source::{Grid, Source};

    fn traced(source: &Source, rect: Rect, params: &Params) -> (Refinement, Trace) {
        let mut quiet = ();
        let mut recorder = Recorder::new(&mut quiet, params);
        let run = refine(source, rect, params, &mut recorder).unwrap();
        let trace = recorder.finish(run.stats.stop).expect("a replayable method");
        (run, trace)
    }

    /// Everything a client sees of a run: vertices, triangles, errors and stats.
    fn seen(r: &Refinement) -> crate::result::RunResult {
        r.clone().into()
    }

    fn sources() -> Vec<(&'static str, Source, Rect)> {
        let expr =
            crate::source::Expression::parse("sin(7*x)*cos(5*y) + exp(-30*((x-0.3)^2+(y-0.6)^2))").unwrap();
        let values =
            (0..65 * 49).map(|k| (((k % 65) as f64) * 0.3).sin() * ((k / 65) as f64 * 0.5).cos()).collect();
        // More nodes than the runs' 1500 vertices: on nodes, a run ends when it matches them all.
        let grid = Grid::new(65, 49, values).unwrap();
        let rect = Rect::new(-1.0, 2.0, 0.0, 1.5).unwrap();
        vec![
            ("expression", Source::Expression(expr).with_domain(rect), rect),
            ("grid", Source::Grid(grid.clone()).with_domain(grid.default_domain()), grid.default_domain()),
        ]
    }

    #[test]
    fn a_prefix_replays_bit_for_bit_as_a_fresh_run_for_every_method_criterion_and_source() {
        for (name, source, rect) in sources() {
            for method in [Method::SemiRecursive, Method::Recursive] {
                for criterion in [Criterion::Error, Criterion::Variation, Criterion::Curvature] {
                    let params = Params::builder(1500).method(method).criterion(criterion).build().unwrap();
                    let (full, trace) = traced(&source, rect, &params);
                    let worst = trace.worst.clone();
                    let tolerances = [worst[200], worst[700] * 1.0001, worst[1200]];
                    for (m, t) in [
                        (4, None),
                        (5, None),
                        (777, None),
                        (1500, None),
                        (1500, Some(tolerances[0])),
                        (1500, Some(tolerances[1])),
                        (900, Some(tolerances[2])),
                    ] {
                        let mut p = Params::builder(m).method(method).criterion(criterion);
                        if let Some(t) = t {
                            p = p.tolerance(t);
                        }
                        let p = p.build().unwrap();
                        let fresh = refine(&source, rect, &p, &mut ()).unwrap();
                        let replayed = replay(&trace, full.mesh.vertices(), m, t).unwrap_or_else(|| {
                            panic!("{name} {method} {criterion} ({m}, {t:?}) not replayed")
                        });
                        assert_eq!(seen(&replayed), seen(&fresh), "{name} {method} {criterion} ({m}, {t:?})");
                    }
                }
            }
        }
    }

    #[test]
    fn a_run_past_the_trace_is_not_replayed() {
        let (_, source, rect) = sources().remove(0);
        let params = Params::new(300).unwrap();
        let (full, trace) = traced(&source, rect, &params);
        assert!(replay(&trace, full.mesh.vertices(), 301, None).is_none());
        // A tolerance the run never reached cannot stop it earlier.
        let lowest = trace.worst.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(replay(&trace, full.mesh.vertices(), 10_000, Some(lowest / 2.0)).is_none());
        // Another run's vertices do not fit this trace.
        let (other, _) =
            traced(&source, rect, &Params::builder(300).method(Method::Recursive).build().unwrap());
        assert!(replay(&trace, other.mesh.vertices(), 300, None).is_none());
        // The cheap test agrees.
        assert!(!trace.covers(300, 301, None));
        assert!(!trace.covers(300, 10_000, Some(lowest / 2.0)));
        assert!(trace.covers(300, 300, None) && trace.covers(300, 10_000, Some(lowest)));
    }

    #[test]
    fn a_data_dependent_run_is_never_replayed_as_its_last_flips_depend_on_where_it_stops() {
        let (_, source, rect) = sources().remove(1);
        let params = Params::builder(300).method(Method::DataDependent).on_grid(true).build().unwrap();
        // Its recorder keeps nothing; a trace that says the method anyway is refused.
        let mut quiet = ();
        let mut recorder = Recorder::new(&mut quiet, &params);
        let full = refine(&source, rect, &params, &mut recorder).unwrap();
        assert!(recorder.finish(full.stats.stop).is_none());
        let (_, mut trace) = traced(&source, rect, &Params::new(300).unwrap());
        trace.method = Method::DataDependent;
        assert!(!trace.covers(300, 300, None) && !trace.covers(300, 200, None));
        assert!(replay(&trace, full.mesh.vertices(), 200, None).is_none());
        assert!(replay(&trace, full.mesh.vertices(), 300, None).is_none());
    }

    #[test]
    fn a_run_that_ran_out_of_edges_answers_every_larger_budget_with_the_same_stop() {
        let (_, source, rect) = sources().remove(0);
        let (full, mut trace) = traced(&source, rect, &Params::new(40).unwrap());
        // As if the traced run had retired its last edge at 40 vertices.
        trace.stop = StopReason::Exhausted;
        let again = replay(&trace, full.mesh.vertices(), 1_000_000, None).unwrap();
        assert_eq!(again.stats.stop, StopReason::Exhausted);
        assert_eq!(again.mesh.vertices(), full.mesh.vertices());
        assert_eq!(
            replay(&trace, full.mesh.vertices(), 40, None).unwrap().stats.stop,
            StopReason::MaxVertices
        );
    }
}
