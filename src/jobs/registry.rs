//! The registry: which jobs exist, who waits on them, the queue's bound and the cache in front.

use super::budget::Budget;
use super::job::{Job, JobError, Record, Snapshot, Status};
use super::share::{Charge, Client, Shares};
use super::{Cache, JobKeys, JobSpec, worker};
use crate::metrics::Metrics;
use crate::refine::trace::replay;
use crate::result::MeshResult;
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::{Notify, Semaphore, watch};

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
        /// Seconds until a place is likely free.
        retry_after: u64,
    },
    /// The job's memory does not fit in the budget now.
    #[error("the job needs {needed} bytes and {available} of the memory budget are free")]
    OverBudget {
        /// Bytes the job needs.
        needed: u64,
        /// Bytes free.
        available: u64,
        /// Seconds until a worker, and its memory, is likely free.
        retry_after: u64,
    },
    /// The client already holds its share of the workers and the queue.
    #[error("this client has {held} jobs running or queued, its share of this server")]
    ShareUsed {
        /// How many jobs the client holds.
        held: usize,
        /// Seconds until one of them is likely done.
        retry_after: u64,
    },
    /// The server is shutting down.
    #[error("the server is shutting down")]
    ShuttingDown,
}

/// A job, a finished job's record, or a cached result, for status queries.
#[derive(Clone)]
pub enum Found {
    /// A job queued or running (or just finished, while clients still read its outcome).
    Job(Arc<Job>),
    /// A finished job.
    Done(Arc<Record>),
    /// A result from the cache with no job record (e.g. after a restart).
    Cached(Arc<MeshResult>),
}

impl Found {
    /// The job's state as clients see it.
    pub fn record(&self) -> Record {
        match self {
            Found::Job(job) => Record::of(&job.snapshot()),
            Found::Done(record) => (**record).clone(),
            Found::Cached(result) => Record::cached(result),
        }
    }
}

/// How many finished job records are kept for status queries (results live in the cache).
pub(super) const FINISHED_KEPT: usize = 10_000;

/// How many families remember their furthest run.
const FAMILIES_KEPT: u64 = 100_000;

/// The job registry, its workers and its cache. Cheap to clone.
#[derive(Clone)]
pub struct Jobs {
    inner: Arc<Inner>,
}

pub(super) struct Inner {
    pub(super) permits: Arc<Semaphore>,
    pub(super) workers: usize,
    pub(super) queue: usize,
    /// Jobs created and not yet holding a permit (some of which will get one at once).
    pub(super) waiting: AtomicUsize,
    /// A std Mutex: held only for map operations, never across an `.await`.
    pub(super) table: Mutex<Table>,
    pub(super) cache: Cache,
    /// Per family, the cached run that went furthest, and its number of steps: the one that
    /// answers the most smaller requests.
    pub(super) families: moka::sync::Cache<String, (String, usize)>,
    pub(super) metrics: Arc<Metrics>,
    pub(super) closed: AtomicBool,
    pub(super) shares: Shares,
    pub(super) budget: Arc<Budget>,
    /// The mean time a job ran, in seconds (f64 bits; a moving average): the basis of every
    /// `Retry-After`.
    pub(super) mean_run: AtomicU64,
}

pub(super) enum Entry {
    Live(Arc<Job>),
    Done(Arc<Record>),
}

#[derive(Default)]
pub(super) struct Table {
    pub(super) jobs: HashMap<String, Entry>,
    pub(super) finished: VecDeque<String>,
}

impl Inner {
    /// Remembers cached run `id` as its family's furthest if it traced more steps than the
    /// one known.
    pub(super) fn note_run(&self, family: &str, id: &str, result: &MeshResult) {
        let Some(steps) = result.trace.as_ref().map(|t| t.splits.len()) else { return };
        if self.families.get(family).is_none_or(|(_, known)| steps >= known) {
            self.families.insert(family.to_owned(), (id.to_owned(), steps));
        }
    }

    /// Jobs waiting beyond the free workers: the queue proper.
    fn queued(&self) -> usize {
        self.waiting.load(Ordering::SeqCst).saturating_sub(self.permits.available_permits())
    }

    /// Whether one more job would wait at most behind `queue` others: it either finds a free
    /// worker or a place in the queue.
    fn has_room(&self) -> bool {
        self.waiting.load(Ordering::SeqCst) < self.queue + self.permits.available_permits()
    }

    /// Seconds until one of `lanes` busy workers is likely free, at the mean time a job has
    /// taken: the `Retry-After` of a refusal, at least 1 s and at most an hour.
    fn retry_after(&self, lanes: usize) -> u64 {
        let mean = f64::from_bits(self.mean_run.load(Ordering::Relaxed));
        (mean / lanes.max(1) as f64).ceil().clamp(1.0, 3600.0) as u64
    }

    /// Folds a job's run time into the mean (weight 1/8: a few jobs move it, one does not).
    pub(super) fn note_run_time(&self, seconds: f64) {
        let _ = self.mean_run.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |bits| {
            Some((f64::from_bits(bits) + (seconds - f64::from_bits(bits)) / 8.0).to_bits())
        });
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
    /// waiting beyond them, of which one client may hold `share` (in (0, 1]), and whose jobs,
    /// bodies and cached meshes share `memory_bytes`.
    pub fn new(
        workers: usize,
        queue: usize,
        share: f64,
        memory_bytes: u64,
        cache: Cache,
        metrics: Arc<Metrics>,
    ) -> Self {
        let cached = cache.clone();
        let budget = Budget::new(memory_bytes, move || cached.memory_bytes_estimate());
        Self {
            inner: Arc::new(Inner {
                permits: Arc::new(Semaphore::new(workers)),
                workers,
                queue,
                waiting: AtomicUsize::new(0),
                table: Mutex::new(Table::default()),
                cache,
                families: moka::sync::Cache::new(FAMILIES_KEPT),
                metrics,
                closed: AtomicBool::new(false),
                shares: Shares::new(share, workers, queue),
                budget,
                mean_run: AtomicU64::new(1f64.to_bits()),
            }),
        }
    }

    /// The metrics the registry updates.
    pub fn metrics(&self) -> &Arc<Metrics> {
        &self.inner.metrics
    }

    /// The memory budget that bodies and jobs are charged to.
    pub fn budget(&self) -> &Arc<Budget> {
        &self.inner.budget
    }

    /// Seconds until a worker, and the memory its job holds, is likely free: the
    /// `Retry-After` of a refusal made outside `submit`.
    pub fn retry_after(&self) -> u64 {
        self.inner.retry_after(self.inner.workers)
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

    /// Answers from the cache, joins an identical job, or starts a new one charged to
    /// `client`. `detached` jobs (from `POST /v1/jobs`) run to the end even when nobody waits.
    ///
    /// # Errors
    /// When the queue is full, the client holds its share, or the server is shutting down.
    pub async fn submit(
        &self,
        keys: JobKeys,
        spec: JobSpec,
        detached: bool,
        client: &Client,
    ) -> Result<Ticket, SubmitError> {
        let inner = &self.inner;
        let JobKeys { id, family } = keys;
        if let Some(finished) = self.cached(&id).await {
            inner.metrics.cache_hits.inc();
            // A run read back from disk after a restart answers its family from now on.
            inner.note_run(&family, &id, &finished);
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
            let waiting = inner.queued();
            return Err(SubmitError::QueueFull { waiting, retry_after: inner.retry_after(inner.workers) });
        }
        let charge: Charge = inner.shares.charge(client).map_err(|held| SubmitError::ShareUsed {
            held,
            retry_after: inner.retry_after(inner.shares.workers),
        })?;
        let memory = inner.budget.charge(spec.memory_bytes()).map_err(|over| {
            inner.metrics.memory_refusals.inc();
            SubmitError::OverBudget {
                needed: over.needed,
                available: over.available,
                retry_after: inner.retry_after(inner.workers),
            }
        })?;
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
            points: Mutex::new(Vec::new()),
        });
        let waiter = inner.attach(&job, detached);
        table.jobs.insert(id, Entry::Live(job.clone()));
        drop(table);
        tokio::spawn(worker::run(self.inner.clone(), job, spec, (charge, memory)));
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
        let spec = spec.mesh()?;
        let (run, _) = self.inner.families.get(family)?;
        let source = self.cached(&run).await?;
        let trace = source.trace.clone()?;
        let (max_vertices, tolerance) = (spec.params.max_vertices(), spec.params.tolerance());
        if !trace.covers(source.vertices.len(), max_vertices, tolerance) {
            return None;
        }
        let (cache, id, spec) = (self.inner.cache.clone(), id.to_owned(), spec.clone());
        crate::cpu::spawn(move || {
            let mut replayed = replay(&trace, &source.vertices, max_vertices, tolerance)?;
            spec.measure(&mut replayed);
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

#[cfg(test)]
mod tests {
    //! The registry on its own: no server, no HTTP; each test drives `Jobs` directly.

    use super::*;
    use crate::api::JobRequest;
    use crate::jobs::{Limits, Outcome, job_keys};
    use crate::refine::StopReason;
    use std::time::Duration;

    fn jobs(workers: usize, queue: usize) -> Jobs {
        let cache = Cache::new(64 << 20, None, 0).unwrap();
        Jobs::new(workers, queue, 1.0, 8 << 30, cache, Arc::new(Metrics::default()))
    }

    fn request(body: serde_json::Value) -> (JobKeys, JobSpec) {
        let limits = Limits {
            max_vertices: 5_000_000,
            max_grid_points: 1000,
            max_expression_len: 100,
            job_time_limit: Duration::from_secs(600),
        };
        let spec =
            JobSpec::from_request(serde_json::from_str::<JobRequest>(&body.to_string()).unwrap(), &limits)
                .unwrap();
        (job_keys(&spec), spec)
    }

    fn client() -> Client {
        Client::from("addr:test".to_owned())
    }

    /// A job long enough to still be running when the test looks again.
    fn long() -> (JobKeys, JobSpec) {
        request(serde_json::json!({"function": "sin(40*x)*cos(40*y)", "max_vertices": 4_000_000}))
    }

    async fn submit(jobs: &Jobs, (keys, spec): (JobKeys, JobSpec), detached: bool) -> Ticket {
        jobs.submit(keys, spec, detached, &client()).await.unwrap_or_else(|e| panic!("refused: {e}"))
    }

    fn waiter(ticket: Ticket) -> Waiter {
        match ticket {
            Ticket::Job(w) => w,
            _ => panic!("expected a job"),
        }
    }

    async fn running(job: &Job) {
        let mut rx = job.subscribe();
        rx.wait_for(|s| s.status != Status::Queued).await.unwrap();
    }

    #[tokio::test]
    async fn identical_submissions_join_one_job_and_the_engine_runs_once() {
        let jobs = jobs(2, 4);
        let body = serde_json::json!({"function": "x*y", "max_vertices": 3000});
        let (a, b) = (
            waiter(submit(&jobs, request(body.clone()), false).await),
            waiter(submit(&jobs, request(body.clone()), false).await),
        );
        assert!(Arc::ptr_eq(a.job(), b.job()));
        assert!(matches!(a.job().outcome().await, Outcome::Succeeded(_)));
        assert_eq!(jobs.metrics().engine_runs.get(), 1);
        assert!(matches!(submit(&jobs, request(body), false).await, Ticket::Cached(_)), "then cached");
    }

    #[tokio::test]
    async fn a_full_queue_refuses_and_counts_who_waits() {
        let jobs = jobs(1, 1);
        let first = waiter(submit(&jobs, long(), true).await);
        running(first.job()).await;
        let queued = waiter(
            submit(&jobs, request(serde_json::json!({"function": "x", "max_vertices": 5})), true).await,
        );
        let refused = jobs
            .submit(
                request(serde_json::json!({"function": "y"})).0,
                request(serde_json::json!({"function": "y"})).1,
                true,
                &client(),
            )
            .await;
        assert!(matches!(refused.err(), Some(SubmitError::QueueFull { waiting: 1, retry_after: 1.. })));
        assert!(!jobs.is_ready());
        first.job().cancel();
        assert!(matches!(queued.job().outcome().await, Outcome::Succeeded(_)), "the queued job runs next");
        assert!(jobs.is_ready());
    }

    #[tokio::test]
    async fn the_last_client_leaving_cancels_a_job_nobody_detached() {
        let jobs = jobs(1, 4);
        let w = waiter(submit(&jobs, long(), false).await);
        let job = w.job().clone();
        running(&job).await;
        drop(w);
        assert_eq!(job.outcome().await, Outcome::Cancelled);
        assert_eq!(job.snapshot().status, Status::Cancelled);
    }

    #[tokio::test]
    async fn a_detached_job_runs_on_with_nobody_waiting() {
        let jobs = jobs(1, 4);
        let body = serde_json::json!({"function": "x*x", "max_vertices": 2000});
        let job = waiter(submit(&jobs, request(body.clone()), true).await).job().clone();
        // Its waiter is gone; it still finishes and is cached.
        assert!(matches!(job.outcome().await, Outcome::Succeeded(_)));
        assert!(matches!(submit(&jobs, request(body), false).await, Ticket::Cached(_)));
    }

    #[tokio::test]
    async fn a_failure_on_the_input_is_answered_again_without_running() {
        let jobs = jobs(1, 4);
        let body = serde_json::json!({"function": "1/(x-0.5)", "max_vertices": 100});
        let w = waiter(submit(&jobs, request(body.clone()), false).await);
        assert!(matches!(w.job().outcome().await, Outcome::Failed(JobError::Refine(_))));
        // The record replaces the live job once the worker files it.
        tokio::task::yield_now().await;
        for _ in 0..1000 {
            if let Ticket::Failed(_) = submit(&jobs, request(body.clone()), false).await {
                assert_eq!(jobs.metrics().engine_runs.get(), 1);
                return;
            }
            tokio::task::yield_now().await;
        }
        panic!("the failure was not answered from the record");
    }

    #[tokio::test]
    async fn a_closed_registry_takes_no_new_job_but_answers_from_the_cache() {
        let jobs = jobs(1, 4);
        let body = serde_json::json!({"function": "x+y", "max_vertices": 50});
        let w = waiter(submit(&jobs, request(body.clone()), false).await);
        w.job().outcome().await;
        jobs.close();
        assert!(matches!(submit(&jobs, request(body), false).await, Ticket::Cached(_)));
        let (keys, spec) = request(serde_json::json!({"function": "x-y"}));
        assert_eq!(jobs.submit(keys, spec, false, &client()).await.err(), Some(SubmitError::ShuttingDown));
    }

    #[tokio::test]
    async fn a_smaller_budget_of_a_cached_run_is_replayed_not_run() {
        let jobs = jobs(1, 4);
        let big = serde_json::json!({"function": "exp(x)*sin(3*y)", "max_vertices": 2000});
        let w = waiter(submit(&jobs, request(big), false).await);
        w.job().outcome().await;
        let small = serde_json::json!({"function": "exp(x)*sin(3*y)", "max_vertices": 700});
        let Ticket::Prefix(result) = submit(&jobs, request(small), false).await else {
            panic!("not a prefix")
        };
        assert_eq!((result.vertices.len(), result.stats.stop()), (700, StopReason::MaxVertices));
        assert_eq!(jobs.metrics().engine_runs.get(), 1);
    }
}
