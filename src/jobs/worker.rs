//! The worker: waits for one of the server's workers ([`super::dispatch`]), refines (with
//! progress and a trace) or solves on the blocking pool, and files the outcome.

use super::admission::Admitted;
use super::dispatch::Worker;
use super::inner::Inner;
use super::job::{Job, JobError, Outcome};
use crate::api::{ProgressEvent, Target};
use crate::geom::Mesh;
use crate::metrics::StateLabel;
use crate::refine::trace::Recorder;
use crate::refine::{Observer, Progress, StopReason, refine};
use crate::result::{RunResult, Stop};
use crate::solve::SolveObserver;
use crate::spec::{JobSpec, Work};
use std::cell::{Cell, RefCell};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::runtime::Handle;

/// Waits for a worker, refines on the blocking pool, stores the result and finishes the job.
pub(super) async fn run(inner: Arc<Inner>, job: Arc<Job>, spec: JobSpec, admitted: Admitted) {
    let permit = inner.admission.worker(&admitted, job.woken()).await;
    inner.metrics.jobs_queued.dec();
    let outcome = match permit {
        Some(permit) if !job.is_cancelled() => {
            job.run();
            inner.metrics.jobs_running.inc();
            inner.metrics.engine_runs.inc();
            let (worker_job, worker) = (job.clone(), inner.clone());
            let turn = Turn {
                worker: RefCell::new(Some(permit)),
                runtime: Handle::current(),
                paused: Cell::default(),
            };
            // The worker goes into the run, which may give it back and take another (a pause),
            // and is dropped as the run ends.
            let outcome = crate::cpu::spawn(move || compute(&worker_job, &spec, &worker, turn))
                .await
                .unwrap_or_else(|e| {
                    tracing::error!(job = %job.id, error = %e, "refinement panicked");
                    (Outcome::Failed(JobError::Internal("the refinement panicked".into())), None)
                });
            inner.metrics.jobs_running.dec();
            if let Some(elapsed) = outcome.1 {
                inner.admission.note_run_time(elapsed.as_secs_f64());
            }
            outcome
        }
        _ => (Outcome::Cancelled, None),
    };
    let (outcome, elapsed) = outcome;
    // Stopped by shutdown with another replica to take it: its clients should ask again.
    let outcome = match outcome {
        Outcome::Cancelled if job.is_handed_back() => Outcome::Failed(JobError::HandedBack),
        outcome => outcome,
    };
    let state = match &outcome {
        Outcome::Succeeded(_) => "succeeded",
        Outcome::Failed(JobError::HandedBack) => "handed_back",
        Outcome::Failed(_) => "failed",
        Outcome::Cancelled => "cancelled",
    };
    inner.metrics.jobs_finished.get_or_create(&StateLabel { state }).inc();
    tracing::info!(job = %job.id, state, "job finished");
    job.finish(outcome, elapsed);
    drop(admitted);
    inner.table.file(&job);
}

/// A job publishes a progress event at most this often, however fast the engine reports: each
/// is a server-sent event, numbered, that every client keeping up receives.
pub const PROGRESS_EVERY: Duration = Duration::from_millis(100);

/// The worker a run holds, which it gives back when a job of a client below its share asks
/// for it (see `dispatch`), and takes again before it goes on.
struct Turn {
    /// `None` once the run was cancelled while it waited for a worker again.
    worker: RefCell<Option<Worker>>,
    /// The runtime the worker is waited for on: the run itself is on a blocking thread.
    runtime: Handle,
    /// How long the run has been paused, in all: not the run's time (see
    /// [`Observer::paused`]).
    paused: Cell<Duration>,
}

impl Turn {
    /// Gives the worker back and waits for one again, when asked to; until the job is
    /// cancelled, then it goes on without one, to stop at once.
    fn yield_if_asked(&self, job: &Job) {
        if !self.worker.borrow().as_ref().is_some_and(Worker::is_asked_to_yield) {
            return;
        }
        let worker = self.worker.borrow_mut().take().expect("held while asked");
        tracing::debug!(job = %job.id, "pausing: another client's job takes the worker");
        let since = Instant::now();
        let resumed = self.runtime.block_on(async {
            let mut turn = std::pin::pin!(worker.take_turn());
            loop {
                tokio::select! {
                    worker = &mut turn => return worker,
                    () = job.woken() => if job.is_cancelled() { return None },
                }
            }
        });
        *self.worker.borrow_mut() = resumed;
        self.paused.set(self.paused.get() + since.elapsed());
    }
}

/// Reports progress into the job's watch channel (a mesh's new vertices first, for viewers),
/// reads its cancel flag, and pauses the run when its worker is asked for.
struct JobObserver<'a> {
    job: &'a Job,
    turn: &'a Turn,
    /// Whether vertices keep their values, so that viewers may be sent each one once: true
    /// for a mesh; a solution's values change with every solve.
    points: bool,
    /// When the last progress event was published.
    published: Option<Instant>,
    /// Where the job stops.
    target: Target,
    /// The first event's worst value, from which the error's progress is measured, and the
    /// fraction last published (never to fall).
    first_worst: Option<f64>,
    fraction: f64,
}

impl JobObserver<'_> {
    /// Publishes `p`, with Newton's steps and residual for a solve, unless one went out less
    /// than [`PROGRESS_EVERY`] ago.
    fn publish(&mut self, mesh: &Mesh, p: &Progress, newton: Option<(u32, f64)>) {
        let now = Instant::now();
        if self.published.is_some_and(|last| now - last < PROGRESS_EVERY) {
            return;
        }
        self.published = Some(now);
        let elapsed_ms = p.elapsed.as_secs_f64() * 1e3;
        let first_worst = *self.first_worst.get_or_insert(p.worst);
        let fraction = self.target.fraction(p.vertices, p.worst, elapsed_ms, first_worst);
        self.fraction = self.fraction.max(fraction);
        let event = ProgressEvent {
            vertices: p.vertices,
            triangles: p.triangles,
            worst: p.worst,
            elapsed_ms,
            target: self.target,
            fraction: self.fraction,
            newton_iterations: newton.map(|n| n.0),
            newton_residual: newton.map(|n| n.1),
        };
        self.job.report(self.points.then(|| mesh.vertices()), event);
    }
}

impl SolveObserver for JobObserver<'_> {
    fn solved(&mut self, mesh: &Mesh, p: &Progress, newton: Option<(u32, f64)>) {
        self.publish(mesh, p, newton);
    }
}

impl Observer for JobObserver<'_> {
    fn progress(&mut self, mesh: &Mesh, p: &Progress) {
        self.publish(mesh, p, None);
    }

    /// Read at every step: the step boundary where a run pauses when its worker is asked for.
    fn is_cancelled(&self) -> bool {
        if self.job.is_cancelled() {
            return true;
        }
        self.turn.yield_if_asked(self.job);
        self.job.is_cancelled()
    }

    fn paused(&self) -> Duration {
        self.turn.paused.get()
    }
}

/// The blocking part: refine (tracing the steps) or solve, and keep the result, with how
/// long the engine ran. A result a time limit stopped goes apart from the cache's answers:
/// another run would reach another vertex count.
fn compute(job: &Job, spec: &JobSpec, inner: &Inner, turn: Turn) -> (Outcome, Option<Duration>) {
    let ms = |d: Option<Duration>| d.map(|d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX));
    let target = match &spec.work {
        Work::Mesh(mesh) => Target {
            max_vertices: mesh.params.max_vertices(),
            tolerance: mesh.params.tolerance(),
            time_limit_ms: ms(mesh.params.time_limit()),
        },
        Work::Solve(solve) => Target {
            max_vertices: solve.settings.max_vertices,
            tolerance: solve.settings.tolerance,
            time_limit_ms: ms(solve.settings.time_limit),
        },
    };
    let points = matches!(spec.work, Work::Mesh(_));
    let mut observer =
        JobObserver { job, turn: &turn, points, published: None, target, first_worst: None, fraction: 0.0 };
    let (mut result, trace, elapsed) = match &spec.work {
        Work::Mesh(mesh) => {
            let mut recorder = Recorder::new(&mut observer, &mesh.params);
            let mut refinement = match refine(&*mesh.source, mesh.domain, &mesh.params, &mut recorder) {
                Ok(r) => r,
                Err(e) => return (Outcome::Failed(JobError::Refine(e)), None),
            };
            let trace = recorder.finish(refinement.stats.stop);
            let elapsed = refinement.elapsed;
            mesh.measure(&mut refinement);
            (RunResult::from(refinement), trace, elapsed)
        }
        Work::Solve(solve) => {
            let adapted = match solve.solve(&mut observer) {
                Ok(a) => a,
                Err(e) => return (Outcome::Failed(JobError::Solve(e)), None),
            };
            let elapsed = adapted.times.last().copied().unwrap_or_default();
            (solve.result(adapted), None, elapsed)
        }
    };
    let elapsed = Some(elapsed);
    let result = match result.stats.stop() {
        Stop::Mesh(StopReason::Cancelled) => return (Outcome::Cancelled, elapsed),
        // Never a family's run to replay from, so no trace to keep.
        Stop::Mesh(StopReason::TimeLimit) => {
            let result = Arc::new(result);
            inner.cache.insert_partial(&job.id, result.clone());
            result
        }
        _ => {
            result.trace = trace.map(Arc::new);
            let result = Arc::new(result);
            inner.cache.insert(&job.id, result.clone());
            if result.trace.is_some() {
                inner.families.note(&job.family, &job.id, &result);
            }
            result
        }
    };
    (Outcome::Succeeded(result), elapsed)
}
