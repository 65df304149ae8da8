//! Jobs: the one bridge between async handlers and the synchronous engine.
//!
//! A submitted [`JobSpec`] gets an id (its canonical hash). A cached result answers at once;
//! an identical job already queued or running is joined; otherwise a new job waits for one of
//! `workers` semaphore permits and then refines on tokio's blocking pool. The tokio docs for
//! `spawn_blocking` recommend exactly this: the blocking pool itself is large, so CPU-bound
//! work needs its own bound.

mod cache;
mod key;
mod spec;

pub use cache::{Cache, Hit};
pub use key::{ENGINE_VERSION, JobKeys, job_id, job_keys};
pub use spec::{DEFAULT_MAX_VERTICES, JobSpec, Limits, SpecError};

use crate::api::ProgressEvent;
use crate::metrics::{Metrics, StateLabel};
use crate::refine::trace::{Recorder, replay};
use crate::refine::{Observer, Progress, RefineError, Stats, StopReason, refine};
use crate::result::MeshResult;
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{Notify, Semaphore, watch};

/// Where a job is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Waiting for a worker.
    Queued,
    /// Refining.
    Running,
    /// Finished with a mesh.
    Succeeded,
    /// Finished with an error.
    Failed,
    /// Stopped before finishing.
    Cancelled,
}

impl Status {
    /// The name used in the API.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Queued => "queued",
            Status::Running => "running",
            Status::Succeeded => "succeeded",
            Status::Failed => "failed",
            Status::Cancelled => "cancelled",
        }
    }
}

/// Why a job failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JobError {
    /// The engine refused the input (F not finite at a point).
    #[error(transparent)]
    Refine(RefineError),
    /// Something went wrong inside the server; the detail is logged, not sent.
    #[error("internal error: {0}")]
    Internal(String),
    /// The job succeeded, but its mesh has since left the cache.
    #[error("the mesh is no longer cached")]
    Evicted,
}

/// How a job ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// With a mesh.
    Succeeded(Arc<MeshResult>),
    /// With an error.
    Failed(JobError),
    /// Cancelled by a client, by every waiting client leaving, or by shutdown.
    Cancelled,
}

/// A job's state as watchers see it. `seq` grows with every change, so server-sent events
/// can carry it as their id and a reconnecting client can skip what it has seen.
#[derive(Debug, Clone)]
pub struct Snapshot {
    /// Increases with every progress report and with the outcome.
    pub seq: u64,
    /// Where the job is.
    pub status: Status,
    /// The latest progress report.
    pub progress: Option<ProgressEvent>,
    /// Set once finished.
    pub outcome: Option<Outcome>,
    /// How long the engine ran, once finished.
    pub elapsed: Option<Duration>,
}

/// One refinement, shared by everyone waiting on it.
pub struct Job {
    id: String,
    /// The id of the requests whose runs are prefixes of this one's (see [`JobKeys`]).
    family: String,
    /// The latest state wins: a slow watcher skips snapshots and the worker never waits on it
    /// (a watch channel, not a queue).
    state: watch::Sender<Snapshot>,
    cancel: AtomicBool,
    cancel_notify: Notify,
    /// Created through `POST /v1/jobs`: runs on even when no client is waiting. Read and
    /// written under the table lock, like `waiters`, so a leaving client and a joining one
    /// cannot both decide.
    detached: AtomicBool,
    waiters: AtomicUsize,
}

impl Job {
    /// The job id.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The current state.
    pub fn snapshot(&self) -> Snapshot {
        self.state.borrow().clone()
    }

    /// A receiver of state changes.
    pub fn subscribe(&self) -> watch::Receiver<Snapshot> {
        self.state.subscribe()
    }

    /// Asks the job to stop: a queued job ends at once, a running one within one insertion.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
        self.cancel_notify.notify_one();
    }

    /// Waits for the outcome.
    pub async fn outcome(&self) -> Outcome {
        let mut rx = self.subscribe();
        loop {
            if let Some(outcome) = rx.borrow_and_update().outcome.clone() {
                return outcome;
            }
            // The sender lives as long as the job, which we hold.
            if rx.changed().await.is_err() {
                return Outcome::Failed(JobError::Internal("job state dropped".into()));
            }
        }
    }

    fn is_finished(&self) -> bool {
        self.state.borrow().outcome.is_some()
    }

    /// Whether a new identical request may join this job instead of starting its own.
    fn is_joinable(&self) -> bool {
        !self.cancel.load(Ordering::Relaxed) && !self.is_finished()
    }

    fn finish(&self, outcome: Outcome, elapsed: Option<Duration>) {
        self.state.send_modify(|s| {
            s.seq += 1;
            s.elapsed = elapsed;
            s.status = match outcome {
                Outcome::Succeeded(_) => Status::Succeeded,
                Outcome::Failed(_) => Status::Failed,
                Outcome::Cancelled => Status::Cancelled,
            };
            s.outcome = Some(outcome);
        });
    }
}

/// A client waiting on a job. When the last one leaves a job that nobody detached, the job is
/// cancelled: a synchronous request or stream whose client hung up.
pub struct Waiter {
    job: Arc<Job>,
    inner: Arc<Inner>,
}

impl Waiter {
    /// The job waited on.
    pub fn job(&self) -> &Arc<Job> {
        &self.job
    }
}

impl Drop for Waiter {
    fn drop(&mut self) {
        let _table = self.inner.table.lock().expect("job table poisoned");
        let last = self.job.waiters.fetch_sub(1, Ordering::SeqCst) == 1;
        if last && !self.job.detached.load(Ordering::SeqCst) && !self.job.is_finished() {
            tracing::info!(job = %self.job.id, "last client left; cancelling");
            self.job.cancel();
        }
    }
}

/// What the table remembers of a finished job: status, stats or error, never the mesh, which
/// lives only in the byte-bounded cache.
#[derive(Debug, Clone)]
pub struct Record {
    /// Succeeded, failed or cancelled.
    pub status: Status,
    /// The last progress report.
    pub progress: Option<ProgressEvent>,
    /// The stats, when succeeded.
    pub stats: Option<Stats>,
    /// The error, when failed.
    pub error: Option<JobError>,
    /// How long the engine ran.
    pub elapsed: Option<Duration>,
}

impl Record {
    fn of(snapshot: &Snapshot) -> Self {
        let (stats, error) = match &snapshot.outcome {
            Some(Outcome::Succeeded(f)) => (Some(f.stats.clone()), None),
            Some(Outcome::Failed(e)) => (None, Some(e.clone())),
            _ => (None, None),
        };
        Self { status: snapshot.status, progress: snapshot.progress, stats, error, elapsed: snapshot.elapsed }
    }
}

/// What a submission found or started.
pub enum Ticket {
    /// The result was cached.
    Cached(Arc<MeshResult>),
    /// The result was replayed from a larger cached run of the same family, without F.
    Prefix(Arc<MeshResult>),
    /// A job, new or already under way, with this client registered as waiting on it (for a
    /// detached submission, the registration is dropped at once and changes nothing).
    Job(Waiter),
    /// An identical job failed on its input before; it would fail the same way again.
    Failed(JobError),
}

/// Why a submission was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SubmitError {
    /// `queue` jobs are already waiting for a worker.
    #[error("{waiting} jobs are waiting for a worker, the most this server queues")]
    QueueFull {
        /// How many wait.
        waiting: usize,
    },
    /// The server is shutting down.
    #[error("the server is shutting down")]
    ShuttingDown,
}

/// A job, a finished job's record, or a cached result, for status queries.
pub enum Found {
    /// A job queued or running (or just finished, while clients still read its outcome).
    Job(Arc<Job>),
    /// A finished job.
    Done(Arc<Record>),
    /// A result from the cache with no job record (e.g. after a restart).
    Cached(Arc<MeshResult>),
}

/// How many finished job records are kept for status queries (results live in the cache).
const FINISHED_KEPT: usize = 10_000;

/// How many families remember their furthest run.
const FAMILIES_KEPT: u64 = 100_000;

/// The job registry, its workers and its cache. Cheap to clone.
#[derive(Clone)]
pub struct Jobs {
    inner: Arc<Inner>,
}

struct Inner {
    permits: Arc<Semaphore>,
    queue: usize,
    /// Jobs created and not yet holding a permit (some of which will get one at once).
    waiting: AtomicUsize,
    /// A std Mutex: held only for map operations, never across an `.await`.
    table: Mutex<Table>,
    cache: Cache,
    /// Per family, the cached run that went furthest, and its number of steps: the one that
    /// answers the most smaller requests.
    families: moka::sync::Cache<String, (String, usize)>,
    metrics: Arc<Metrics>,
    closed: AtomicBool,
}

enum Entry {
    Live(Arc<Job>),
    Done(Arc<Record>),
}

#[derive(Default)]
struct Table {
    jobs: HashMap<String, Entry>,
    finished: VecDeque<String>,
}

impl Inner {
    /// Jobs waiting beyond the free workers: the queue proper.
    fn queued(&self) -> usize {
        self.waiting.load(Ordering::SeqCst).saturating_sub(self.permits.available_permits())
    }

    /// Whether one more job would wait at most behind `queue` others: it either finds a free
    /// worker or a place in the queue.
    fn has_room(&self) -> bool {
        self.waiting.load(Ordering::SeqCst) < self.queue + self.permits.available_permits()
    }

    fn attach(self: &Arc<Self>, job: &Arc<Job>, detached: bool) -> Waiter {
        // Caller holds the table lock.
        job.waiters.fetch_add(1, Ordering::SeqCst);
        if detached {
            job.detached.store(true, Ordering::SeqCst);
        }
        Waiter { job: job.clone(), inner: self.clone() }
    }
}

impl Jobs {
    /// A registry running at most `workers` refinements at once, with at most `queue` jobs
    /// waiting beyond them.
    pub fn new(workers: usize, queue: usize, cache: Cache, metrics: Arc<Metrics>) -> Self {
        Self {
            inner: Arc::new(Inner {
                permits: Arc::new(Semaphore::new(workers)),
                queue,
                waiting: AtomicUsize::new(0),
                table: Mutex::new(Table::default()),
                cache,
                families: moka::sync::Cache::new(FAMILIES_KEPT),
                metrics,
                closed: AtomicBool::new(false),
            }),
        }
    }

    /// The metrics the registry updates.
    pub fn metrics(&self) -> &Arc<Metrics> {
        &self.inner.metrics
    }

    /// Bytes of meshes cached in memory.
    pub fn cache_bytes(&self) -> u64 {
        self.inner.cache.memory_bytes()
    }

    /// Bytes of the mesh files this server has indexed in the cache directory.
    pub fn cache_disk_bytes(&self) -> u64 {
        self.inner.cache.disk_bytes()
    }

    /// Whether a new job would be accepted now.
    pub fn is_ready(&self) -> bool {
        !self.inner.closed.load(Ordering::SeqCst) && self.inner.has_room()
    }

    /// Answers from the cache, joins an identical job, or starts a new one. `detached` jobs
    /// (from `POST /v1/jobs`) run to the end even when nobody waits.
    ///
    /// # Errors
    /// When the queue is full or the server is shutting down.
    pub async fn submit(&self, keys: JobKeys, spec: JobSpec, detached: bool) -> Result<Ticket, SubmitError> {
        let inner = &self.inner;
        let JobKeys { id, family } = keys;
        if let Some(finished) = self.cached(&id).await {
            inner.metrics.cache_hits.inc();
            return Ok(Ticket::Cached(finished));
        }
        if let Some(result) = self.prefix(&id, &family, &spec).await {
            inner.metrics.prefix_hits.inc();
            return Ok(Ticket::Prefix(result));
        }
        let mut table = inner.table.lock().expect("job table poisoned");
        match table.jobs.get(&id) {
            Some(Entry::Live(job)) if job.is_joinable() => {
                inner.metrics.cache_misses.inc();
                return Ok(Ticket::Job(inner.attach(job, detached)));
            }
            Some(Entry::Done(record)) => match &record.error {
                // A failure on the input is deterministic: it is the answer again.
                Some(e @ JobError::Refine(_)) => {
                    inner.metrics.cache_misses.inc();
                    return Ok(Ticket::Failed(e.clone()));
                }
                _ if record.status == Status::Succeeded => {
                    // It may have been cached between the lookup above and the lock.
                    if let Some(finished) = inner.cache.get_memory(&id) {
                        inner.metrics.cache_hits.inc();
                        return Ok(Ticket::Cached(finished));
                    }
                }
                // Cancelled, an internal error, or a mesh evicted from the cache: run again.
                _ => {}
            },
            // A job being cancelled, or none: start a new one.
            _ => {}
        }
        inner.metrics.cache_misses.inc();
        if inner.closed.load(Ordering::SeqCst) {
            return Err(SubmitError::ShuttingDown);
        }
        if !inner.has_room() {
            return Err(SubmitError::QueueFull { waiting: inner.queued() });
        }
        inner.waiting.fetch_add(1, Ordering::SeqCst);
        inner.metrics.jobs_queued.inc();
        let (state, _) = watch::channel(Snapshot {
            seq: 0,
            status: Status::Queued,
            progress: None,
            outcome: None,
            elapsed: None,
        });
        let job = Arc::new(Job {
            id: id.clone(),
            family,
            state,
            cancel: AtomicBool::new(false),
            cancel_notify: Notify::new(),
            detached: AtomicBool::new(detached),
            waiters: AtomicUsize::new(0),
        });
        let waiter = inner.attach(&job, detached);
        table.jobs.insert(id, Entry::Live(job.clone()));
        drop(table);
        tokio::spawn(run(self.inner.clone(), job, spec));
        Ok(Ticket::Job(waiter))
    }

    /// The job, finished job or cached result with this id.
    pub async fn find(&self, id: &str) -> Option<Found> {
        let found = match self.inner.table.lock().expect("job table poisoned").jobs.get(id) {
            Some(Entry::Live(job)) => Some(Found::Job(job.clone())),
            Some(Entry::Done(record)) => Some(Found::Done(record.clone())),
            None => None,
        };
        match found {
            Some(found) => Some(found),
            None => self.cached(id).await.map(Found::Cached),
        }
    }

    /// Registers a client waiting on job `id` while it runs (server-sent events).
    pub fn watch(&self, id: &str) -> Option<Waiter> {
        let table = self.inner.table.lock().expect("job table poisoned");
        match table.jobs.get(id) {
            Some(Entry::Live(job)) => Some(self.inner.attach(job, false)),
            _ => None,
        }
    }

    /// The result of `spec` replayed from the furthest cached run of its family, stored under
    /// `id`; `None` when there is no such run or the request goes past it.
    async fn prefix(&self, id: &str, family: &str, spec: &JobSpec) -> Option<Arc<MeshResult>> {
        let (run, _) = self.inner.families.get(family)?;
        let source = self.cached(&run).await?;
        let trace = source.trace.clone()?;
        let (cache, id) = (self.inner.cache.clone(), id.to_owned());
        let (max_vertices, tolerance) = (spec.params.max_vertices(), spec.params.tolerance());
        tokio::task::spawn_blocking(move || {
            let replayed = replay(&trace, &source.vertices, max_vertices, tolerance)?;
            let result = Arc::new(MeshResult::from(replayed));
            cache.insert(&id, result.clone());
            Some(result)
        })
        .await
        .ok()
        .flatten()
    }

    /// The result a time limit stopped for job `id`, if still held (never a new request's
    /// answer; see [`Cache::insert_partial`]).
    pub fn partial(&self, id: &str) -> Option<Arc<MeshResult>> {
        self.inner.cache.get_partial(id)
    }

    /// The cached mesh with this id, if any.
    pub async fn cached(&self, id: &str) -> Option<Arc<MeshResult>> {
        let cache = &self.inner.cache;
        if let Some(f) = cache.get_memory(id) {
            return Some(f);
        }
        if !cache.has_disk() {
            return None;
        }
        let (cache, id) = (cache.clone(), id.to_owned());
        tokio::task::spawn_blocking(move || cache.get(&id).map(|(f, _)| f)).await.ok().flatten()
    }

    /// Refuses new jobs from now on.
    pub fn close(&self) {
        self.inner.closed.store(true, Ordering::SeqCst);
    }

    /// Cancels every job not yet finished.
    pub fn cancel_all(&self) {
        for entry in self.inner.table.lock().expect("job table poisoned").jobs.values() {
            if let Entry::Live(job) = entry {
                job.cancel();
            }
        }
    }

    /// Whether any job is queued or running.
    pub fn is_busy(&self) -> bool {
        let table = self.inner.table.lock().expect("job table poisoned");
        table.jobs.values().any(|e| matches!(e, Entry::Live(_)))
    }
}

/// Waits for a permit, refines on the blocking pool, stores the result and finishes the job.
async fn run(inner: Arc<Inner>, job: Arc<Job>, spec: JobSpec) {
    let permit = tokio::select! {
        permit = inner.permits.clone().acquire_owned() => permit.ok(),
        () = job.cancel_notify.notified() => None,
    };
    inner.waiting.fetch_sub(1, Ordering::SeqCst);
    inner.metrics.jobs_queued.dec();
    let outcome = match permit {
        Some(permit) if !job.cancel.load(Ordering::Relaxed) => {
            job.state.send_modify(|s| s.status = Status::Running);
            inner.metrics.jobs_running.inc();
            inner.metrics.engine_runs.inc();
            let (worker_job, worker) = (job.clone(), inner.clone());
            let outcome = tokio::task::spawn_blocking(move || compute(&worker_job, &spec, &worker))
                .await
                .unwrap_or_else(|e| {
                    tracing::error!(job = %job.id, error = %e, "refinement panicked");
                    (Outcome::Failed(JobError::Internal("the refinement panicked".into())), None)
                });
            inner.metrics.jobs_running.dec();
            drop(permit);
            outcome
        }
        _ => (Outcome::Cancelled, None),
    };
    let (outcome, elapsed) = outcome;
    let state = match &outcome {
        Outcome::Succeeded(_) => "succeeded",
        Outcome::Failed(_) => "failed",
        Outcome::Cancelled => "cancelled",
    };
    inner.metrics.jobs_finished.get_or_create(&StateLabel { state }).inc();
    tracing::info!(job = %job.id, state, "job finished");
    job.finish(outcome, elapsed);
    // Waiting clients hold the job (and its mesh) until they have read it; the table keeps
    // only the record.
    let record = Arc::new(Record::of(&job.snapshot()));
    let mut table = inner.table.lock().expect("job table poisoned");
    if matches!(table.jobs.get(&job.id), Some(Entry::Live(j)) if Arc::ptr_eq(j, &job)) {
        table.jobs.insert(job.id.clone(), Entry::Done(record));
        table.finished.push_back(job.id.clone());
    }
    while table.finished.len() > FINISHED_KEPT {
        let oldest = table.finished.pop_front().expect("non-empty");
        if matches!(table.jobs.get(&oldest), Some(Entry::Done(_))) {
            table.jobs.remove(&oldest);
        }
    }
}

/// Reports progress into the job's watch channel and reads its cancel flag.
struct JobObserver<'a> {
    job: &'a Job,
}

impl Observer for JobObserver<'_> {
    fn progress(&mut self, p: &Progress) {
        let event = ProgressEvent {
            vertices: p.vertices,
            triangles: p.triangles,
            worst: p.worst,
            elapsed_ms: p.elapsed.as_secs_f64() * 1e3,
        };
        self.job.state.send_modify(|s| {
            s.seq += 1;
            s.progress = Some(event);
        });
    }

    fn is_cancelled(&self) -> bool {
        self.job.cancel.load(Ordering::Relaxed)
    }
}

/// The blocking part: refine, tracing the steps, and keep the result, with how long the
/// engine ran. A result a time limit stopped goes apart from the cache's answers: another
/// run would reach another vertex count.
fn compute(job: &Job, spec: &JobSpec, inner: &Inner) -> (Outcome, Option<Duration>) {
    let mut observer = JobObserver { job };
    let mut recorder = Recorder::new(&mut observer, spec.params.method(), spec.params.criterion());
    let refinement = match refine(&*spec.source, spec.domain, &spec.params, &mut recorder) {
        Ok(r) => r,
        Err(e) => return (Outcome::Failed(JobError::Refine(e)), None),
    };
    let trace = recorder.finish(refinement.stats.stop);
    let elapsed = Some(refinement.elapsed);
    let steps = trace.splits.len();
    let result = Arc::new(MeshResult { trace: Some(Arc::new(trace)), ..MeshResult::from(refinement) });
    match result.stats.stop {
        StopReason::Cancelled => return (Outcome::Cancelled, elapsed),
        StopReason::TimeLimit => inner.cache.insert_partial(&job.id, result.clone()),
        _ => {
            inner.cache.insert(&job.id, result.clone());
            let further = inner.families.get(&job.family).is_none_or(|(_, known)| steps >= known);
            if further {
                inner.families.insert(job.family.clone(), (job.id.clone(), steps));
            }
        }
    }
    (Outcome::Succeeded(result), elapsed)
}
