//! The registry: [`Jobs`], the one public face of the jobs: submit, find, watch, cancel, shut
//! down. Each part it is made of owns its state (see [`Inner`]).

use super::admission::{Admission, Pool, SubmitError};
use super::budget::Budget;
use super::families::Families;
use super::inner::Inner;
use super::job::{Job, JobError, Lifetime, Record, Status};
use super::replica::follow::{self, Fetched};
use super::replica::lease::Lease;
use super::replica::peers::{self, Acquired, Alone, Control, Kept, KeptRequest, Peers, Take};
use super::replica::{RequestParser, takeover};
use super::share::Client;
use super::start::Start;
use super::table::{Joined, Listing, Table, Waiter};
use super::ticket::Ticket;
use super::{Cache, JobKeys, JobSpec};
use crate::metrics::Metrics;
use crate::refine::trace::replay;
use crate::result::MeshResult;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// A job, a finished job's record, or a cached result, for status queries.
#[derive(Clone)]
pub enum Found {
    /// A job queued or running (or just finished, while clients still read its outcome).
    Job(Arc<Job>),
    /// A finished job.
    Done(Arc<Record>),
    /// A result from the cache with no job record (e.g. after a restart).
    Cached(Arc<MeshResult>),
    /// A job queued or running on another replica, as its last posting says.
    Remote(Arc<Record>),
}

impl Found {
    /// The job's state as clients see it.
    pub fn record(&self) -> Record {
        match self {
            Found::Job(job) => Record::of(&job.snapshot()),
            Found::Done(record) | Found::Remote(record) => (**record).clone(),
            Found::Cached(result) => Record::cached(result),
        }
    }
}

/// Whether run `token` of job `id` has posted its end (and is about to let go of
/// its lease), or was asked to stop: a new request must not be given its end.
async fn has_ended(peers: &dyn Peers, id: &str, token: &str) -> bool {
    let ended = matches!(peers.posting(id).await, Ok(Some(r)) if r.run == token && r.is_final());
    ended || matches!(peers.asked(id).await, Ok((true, _)))
}

/// How often a submission looks again at a run that holds the job's lease and will not run
/// it for this request: one of this replica being started by a concurrent identical request
/// (to join), or one that has ended, or was asked to, and not yet let go of its lease (for at
/// most a lease, then the submission is refused with `Retry-After`).
const OWN_RUN_WAIT: Duration = Duration::from_millis(25);

/// How many results being read from the store keep their turn (see [`follow::fetch`]).
const FETCHES_KEPT: u64 = 10_000;

/// The job registry, its workers and its cache. Cheap to clone.
#[derive(Clone)]
pub struct Jobs {
    inner: Arc<Inner>,
}

/// Gives a lease back unless disarmed: a submission abandoned between taking a lease and
/// starting its run (its client hung up, or the run was refused) leaves no lease behind.
struct LeaseGuard {
    peers: Arc<dyn Peers>,
    id: String,
    token: Option<String>,
}

impl LeaseGuard {
    fn disarm(&mut self) {
        self.token = None;
    }
}

impl Drop for LeaseGuard {
    fn drop(&mut self) {
        if let (Some(token), Ok(runtime)) = (self.token.take(), tokio::runtime::Handle::try_current()) {
            let (peers, id) = (self.peers.clone(), std::mem::take(&mut self.id));
            runtime.spawn(async move { peers.release(&id, &token).await });
        }
    }
}

impl Jobs {
    /// A registry of the workers, queue, shares and memory budget of `pool`, in front of
    /// `cache`, on its own until [`shared`](Self::shared).
    pub fn new(pool: &Pool, cache: Cache, metrics: Arc<Metrics>) -> Self {
        let cached = cache.clone();
        Self {
            inner: Arc::new(Inner {
                table: Table::new(),
                admission: Admission::new(pool, move || cached.memory_bytes_estimate()),
                cache,
                families: Families::new(),
                metrics,
                peers: Arc::new(Alone),
                fetching: moka::sync::Cache::new(FETCHES_KEPT),
                publishing: AtomicUsize::new(0),
            }),
        }
    }

    /// Shares results and jobs with the other replicas through `peers`, in place of the
    /// store-less `peers::Alone`; `parser` reads the requests of jobs taken over. Call it before
    /// the registry is cloned, from within the runtime.
    ///
    /// # Panics
    /// When the registry has been cloned.
    #[must_use]
    pub fn shared(mut self, peers: Arc<dyn Peers>, parser: Arc<dyn RequestParser>) -> Self {
        let inner = Arc::get_mut(&mut self.inner).expect("shared before the registry is cloned");
        let messages = peers.messages();
        inner.peers = peers;
        tokio::spawn(follow::dispatch(Arc::downgrade(&self.inner), messages));
        tokio::spawn(takeover::sweep(Arc::downgrade(&self.inner), parser));
        self
    }

    /// Whether replicas share through the store, and if so whether the store answered last.
    pub fn redis(&self) -> Option<bool> {
        let peers = &self.inner.peers;
        peers.is_shared().then(|| peers.is_up())
    }

    /// The metrics the registry updates.
    pub fn metrics(&self) -> &Arc<Metrics> {
        &self.inner.metrics
    }

    /// The memory budget that bodies and jobs are charged to.
    pub fn budget(&self) -> &Arc<Budget> {
        self.inner.admission.budget()
    }

    /// Seconds until a worker, and the memory its job holds, is likely free: the
    /// `Retry-After` of a refusal made outside `submit`.
    pub fn retry_after(&self) -> u64 {
        self.inner.admission.retry_after()
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
        self.inner.admission.is_ready()
    }

    /// Answers from the cache, joins an identical job, or starts a new one charged to
    /// `client`, to run for `lifetime`.
    ///
    /// # Errors
    /// When the queue is full, the client holds its share, or the server is shutting down.
    pub async fn submit(
        &self,
        keys: JobKeys,
        spec: JobSpec,
        lifetime: Lifetime,
        client: &Client,
    ) -> Result<Ticket, SubmitError> {
        self.submit_request(keys, spec, lifetime, client, None).await
    }

    /// As [`submit`](Self::submit); when replicas share through the store, a job this replica
    /// runs keeps `request` there, so that another replica can take it over, and a job
    /// another replica runs is followed rather than run again.
    ///
    /// # Errors
    /// As [`submit`](Self::submit).
    pub async fn submit_request(
        &self,
        keys: JobKeys,
        spec: JobSpec,
        lifetime: Lifetime,
        client: &Client,
        request: Option<KeptRequest>,
    ) -> Result<Ticket, SubmitError> {
        let inner = &self.inner;
        let JobKeys { id, family } = keys;
        if let Some(finished) = self.cached(&id).await {
            inner.metrics.cache_hits.inc();
            // A run read back from disk after a restart answers its family from now on.
            inner.families.note(&family, &id, &finished);
            return Ok(Ticket::Cached(finished));
        }
        if let Some(result) = self.prefix(&id, &family, &spec).await {
            inner.metrics.prefix_hits.inc();
            return Ok(Ticket::Prefix(result));
        }
        if let Some(ticket) = self.join(&id, lifetime) {
            return Ok(ticket);
        }
        let peers = &*inner.peers;
        // One replica runs a job: the one whose run takes its lease. Guarded from before the
        // first try: a client hanging up while the lease is being taken leaves none behind.
        let token = peers.token();
        // (A replica alone takes no lease, and has none to give back.)
        let mut guard = LeaseGuard {
            peers: inner.peers.clone(),
            id: id.clone(),
            token: peers.is_shared().then(|| token.clone()),
        };
        // An ended run lets go of its lease within a lease, even if its release was lost.
        let patience = (peers.lease() + Duration::from_secs(1)).as_millis() / OWN_RUN_WAIT.as_millis();
        let mut waits: u128 = 0;
        let won = loop {
            let held = match peers.acquire(&id, &token, Take::Fresh).await {
                Ok(Acquired::Won) => break true,
                Ok(Acquired::Held(holder)) => holder,
                // The store is away, or there is none: run it here, unshared.
                Err(_) => break false,
            };
            waits += 1;
            if peers.is_mine(&held) {
                // A run of this replica: one a concurrent identical request is starting (join
                // it), or one ending after a cancel (let it end, then run again). Never a
                // mirror of it.
                if let Some(ticket) = self.join(&id, lifetime) {
                    return Ok(ticket);
                }
            } else if !has_ended(peers, &id, &held).await {
                inner.metrics.cache_misses.inc();
                return Ok(Ticket::Job(follow::follow(inner, id, family, Some(held))));
            }
            // A run that has ended, or was asked to, and not yet let go: wait for its lease.
            if waits >= patience {
                return Err(inner.admission.queue_full());
            }
            tokio::time::sleep(OWN_RUN_WAIT).await;
        };
        if !won {
            let start = Start { id, family, seq: 0, lease: None, request: None };
            return inner.start(start, spec, lifetime, client).map(|(ticket, _)| ticket);
        }
        // Finished elsewhere between the lookup above and the lease.
        if let Fetched::Found(result) = follow::fetch(inner, &id, Kept::Whole).await {
            inner.metrics.cache_hits.inc();
            return Ok(Ticket::Cached(result));
        }
        let (announced, first_posting) = tokio::sync::oneshot::channel();
        let lease = Lease { token, announced: Some(announced) };
        let start = Start { id, family, seq: 0, lease: Some(lease), request };
        let (ticket, started) = inner.start(start, spec, lifetime, client)?;
        if started {
            guard.disarm();
            // Stored before the client hears of the job, so that any replica finds it at once.
            let _ = first_posting.await;
        }
        Ok(ticket)
    }

    /// Answers from the table: joins a live job, repeats a failure on the input, or finds a
    /// result cached since the caller's lookup.
    fn join(&self, id: &str, lifetime: Lifetime) -> Option<Ticket> {
        let inner = &self.inner;
        match inner.table.join(id, lifetime)? {
            Joined::Job(waiter) => {
                inner.metrics.cache_misses.inc();
                Some(Ticket::Job(waiter))
            }
            Joined::Done(record) => match &record.error {
                // A failure on the input is deterministic: it is the answer again.
                Some(e @ JobError::Refine(_)) => {
                    inner.metrics.cache_misses.inc();
                    Some(Ticket::Failed(e.clone()))
                }
                // It may have been cached between the lookup and the table's answer.
                _ if record.status == Status::Succeeded => {
                    let finished = inner.cache.get_memory(id)?;
                    inner.metrics.cache_hits.inc();
                    Some(Ticket::Cached(finished))
                }
                // Cancelled, an internal error, or a mesh evicted from the cache: run again.
                _ => None,
            },
        }
    }

    /// The result of `spec` replayed from the furthest cached run of its family, stored under
    /// `id`; `None` when there is no such run or the request goes past it.
    async fn prefix(&self, id: &str, family: &str, spec: &JobSpec) -> Option<Arc<MeshResult>> {
        let spec = spec.mesh()?;
        let run = self.inner.families.furthest(family)?;
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

    /// The job, finished job or cached result with this id: on this replica, or, when
    /// replicas share, on any.
    pub async fn find(&self, id: &str) -> Option<Found> {
        let found = match self.inner.table.get(id) {
            Some(Listing::Live(job)) => Some(Found::Job(job)),
            Some(Listing::Done(record)) => Some(Found::Done(record)),
            None => None,
        };
        match &found {
            // A job that failed or was cancelled here may have run again elsewhere since.
            Some(Found::Done(record))
                if record.status != Status::Succeeded && self.inner.peers.is_shared() => {}
            Some(_) => return found,
            None => {}
        }
        if let Some(result) = self.cached(id).await {
            return Some(Found::Cached(result));
        }
        let peers = &*self.inner.peers;
        let posting = match peers.posting(id).await.ok().flatten() {
            Some(posting) => posting,
            // A job whose run has taken its lease and not yet posted.
            None if matches!(peers.holder(id).await, Ok(Some(_))) => {
                return Some(Found::Remote(Arc::new(Record::queued())));
            }
            None => return found,
        };
        Some(match follow::record(&posting) {
            // The end of an earlier run, while a new one holds the lease.
            Some(_) if matches!(peers.holder(id).await, Ok(Some(h)) if h != posting.run) => {
                Found::Remote(Arc::new(Record::queued()))
            }
            Some(done) => Found::Done(Arc::new(done)),
            None => Found::Remote(Arc::new(follow::view(&posting))),
        })
    }

    /// Registers a client waiting on job `id` while it runs (server-sent events), here or,
    /// when replicas share, on another replica.
    pub async fn watch(&self, id: &str) -> Option<Waiter> {
        match self.inner.table.watch(id) {
            Ok(waiter) => return Some(waiter),
            Err(Some(r)) if r.status == Status::Succeeded => return None,
            // A job that failed or was cancelled here may run again elsewhere, and one
            // unknown here may run on another replica.
            Err(_) => {}
        }
        let peers = &*self.inner.peers;
        let (holder, posting) = (peers.holder(id).await.ok()?, peers.posting(id).await.ok()?);
        let running = match (&holder, &posting) {
            // A run holds the lease and has not stored its end.
            (Some(h), posting) => posting.as_ref().is_none_or(|r| !(r.run == *h && r.is_final())),
            // None does, and its posting is not an end: a takeover is due, or it is lost (the
            // mirror finds out which).
            (None, posting) => posting.as_ref().is_some_and(|r| !r.is_final()),
        };
        running.then(|| follow::follow(&self.inner, id.to_owned(), id.to_owned(), holder))
    }

    /// Asks job `job` to stop, wherever it runs.
    ///
    /// # Errors
    /// When another replica runs it and the store cannot be reached to tell it.
    pub async fn cancel(&self, job: &Job) -> Result<(), peers::Unavailable> {
        if job.follows {
            return self.inner.peers.control(&job.id, Control::Cancel).await;
        }
        job.cancel();
        Ok(())
    }

    /// The result a time limit stopped for job `id`, if still held here or, when replicas
    /// share, in the store (never a new request's answer; see [`Cache::insert_partial`]).
    pub async fn partial(&self, id: &str) -> Option<Arc<MeshResult>> {
        match self.inner.cache.get_partial(id) {
            Some(result) => Some(result),
            None => follow::fetch(&self.inner, id, Kept::Partial).await.found(),
        }
    }

    /// The cached mesh with this id, if any.
    pub async fn cached(&self, id: &str) -> Option<Arc<MeshResult>> {
        let cache = &self.inner.cache;
        if let Some(f) = cache.get_memory(id) {
            return Some(f);
        }
        if cache.has_disk() {
            let (cache, id) = (cache.clone(), id.to_owned());
            let found = tokio::task::spawn_blocking(move || cache.get(&id).map(|(f, _)| f)).await;
            if let Ok(Some(found)) = found {
                return Some(found);
            }
        }
        follow::fetch(&self.inner, id, Kept::Whole).await.found()
    }

    /// Refuses new jobs from now on.
    pub fn close(&self) {
        self.inner.admission.close();
    }

    /// Cancels every job not yet finished; when replicas share, hands them back for another
    /// replica to take over instead (a job followed from another replica runs on there).
    pub fn cancel_all(&self) {
        self.inner.table.stop_all();
    }

    /// Whether any job is queued or running, or still being told to the store.
    pub fn is_busy(&self) -> bool {
        self.inner.publishing.load(Ordering::SeqCst) > 0 || self.inner.table.is_busy()
    }
}

#[cfg(test)]
impl Jobs {
    /// Takes a worker, as a job would: tests hold every worker to keep jobs queued, and so
    /// decide when the engine runs.
    pub(super) async fn hold_worker(&self) -> super::dispatch::Worker {
        self.inner.admission.hold_worker().await
    }
}

#[cfg(test)]
mod tests {
    //! The registry on its own: no server, no HTTP; each test drives `Jobs` directly.

    use super::*;
    use crate::api::JobRequest;
    use crate::jobs::{JobError, Limits, Outcome, job_keys};
    use crate::refine::StopReason;
    use std::num::NonZeroUsize;
    use std::time::Duration;

    fn jobs(workers: usize, queue: usize) -> Jobs {
        let cache = Cache::new(64 << 20, None, 0).unwrap();
        let workers = NonZeroUsize::new(workers).unwrap();
        let pool = Pool { workers, queue, client_share: 1.0, memory_bytes: 8 << 30 };
        Jobs::new(&pool, cache, Arc::new(Metrics::default()))
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

    async fn submit(jobs: &Jobs, (keys, spec): (JobKeys, JobSpec), lifetime: Lifetime) -> Ticket {
        jobs.submit(keys, spec, lifetime, &client()).await.unwrap_or_else(|e| panic!("refused: {e}"))
    }

    fn waiter(ticket: Ticket) -> Waiter {
        match ticket {
            Ticket::Job(w) => w,
            _ => panic!("expected a job"),
        }
    }

    #[tokio::test]
    async fn identical_submissions_join_one_job_and_the_engine_runs_once() {
        let jobs = jobs(2, 4);
        let body = serde_json::json!({"function": "x*y", "max_vertices": 3000});
        let (a, b) = (
            waiter(submit(&jobs, request(body.clone()), Lifetime::WhileWaited).await),
            waiter(submit(&jobs, request(body.clone()), Lifetime::WhileWaited).await),
        );
        assert!(Arc::ptr_eq(a.job(), b.job()));
        assert!(matches!(a.job().outcome().await, Outcome::Succeeded(_)));
        assert_eq!(jobs.metrics().engine_runs.get(), 1);
        assert!(
            matches!(submit(&jobs, request(body), Lifetime::WhileWaited).await, Ticket::Cached(_)),
            "then cached"
        );
    }

    #[tokio::test]
    async fn a_replica_alone_shares_nothing_and_cancels_rather_than_hands_back_at_shutdown() {
        let jobs = jobs(1, 4);
        assert_eq!(jobs.redis(), None, "no store to report on");
        let held = jobs.hold_worker().await;
        let body = serde_json::json!({"function": "x*y", "max_vertices": 500});
        let job = waiter(submit(&jobs, request(body.clone()), Lifetime::Detached).await).job().clone();
        assert!(!job.follows);
        // Nothing is published, so shutdown waits on the job alone.
        assert_eq!(jobs.inner.publishing.load(Ordering::SeqCst), 0);
        assert!(jobs.find(&job.id).await.is_some_and(|f| matches!(f, Found::Job(_))));
        jobs.cancel_all();
        drop(held);
        // No other replica could take it over: cancelled, not handed back.
        assert_eq!(job.outcome().await, Outcome::Cancelled);
        assert!(jobs.watch(&job.id).await.is_none(), "nothing to follow elsewhere");
    }

    #[tokio::test]
    async fn a_full_queue_refuses_and_counts_who_waits() {
        let jobs = jobs(1, 1);
        // The only worker is busy: the next job waits, and fills the queue.
        let busy = jobs.hold_worker().await;
        let queued = waiter(
            submit(
                &jobs,
                request(serde_json::json!({"function": "x", "max_vertices": 5})),
                Lifetime::Detached,
            )
            .await,
        );
        let (keys, spec) = request(serde_json::json!({"function": "y"}));
        let refused = jobs.submit(keys, spec, Lifetime::Detached, &client()).await;
        assert!(matches!(refused.err(), Some(SubmitError::QueueFull { waiting: 1, retry_after: 1.. })));
        assert!(!jobs.is_ready());
        drop(busy);
        assert!(matches!(queued.job().outcome().await, Outcome::Succeeded(_)), "the queued job runs next");
        assert!(jobs.is_ready());
    }

    #[tokio::test]
    async fn the_last_client_leaving_cancels_a_job_nobody_detached() {
        let jobs = jobs(1, 4);
        let busy = jobs.hold_worker().await;
        let (first, second) = (
            waiter(
                submit(&jobs, request(serde_json::json!({"function": "x*x"})), Lifetime::WhileWaited).await,
            ),
            waiter(
                submit(&jobs, request(serde_json::json!({"function": "x*x"})), Lifetime::WhileWaited).await,
            ),
        );
        let job = first.job().clone();
        drop(first);
        assert!(!job.is_finished(), "a client still waits");
        drop(second);
        assert_eq!(job.outcome().await, Outcome::Cancelled);
        assert_eq!(job.snapshot().status, Status::Cancelled);
        drop(busy);
        // The freed worker runs the next job, and only it.
        let next = waiter(
            submit(&jobs, request(serde_json::json!({"function": "y*y"})), Lifetime::WhileWaited).await,
        );
        assert!(matches!(next.job().outcome().await, Outcome::Succeeded(_)));
        assert_eq!(jobs.metrics().engine_runs.get(), 1, "the cancelled job never ran");
    }

    #[tokio::test]
    async fn a_detached_job_runs_on_with_nobody_waiting() {
        let jobs = jobs(1, 4);
        let body = serde_json::json!({"function": "x*x", "max_vertices": 2000});
        let job = waiter(submit(&jobs, request(body.clone()), Lifetime::Detached).await).job().clone();
        // Its waiter is gone; it still finishes and is cached.
        assert!(matches!(job.outcome().await, Outcome::Succeeded(_)));
        assert!(matches!(submit(&jobs, request(body), Lifetime::WhileWaited).await, Ticket::Cached(_)));
    }

    #[tokio::test]
    async fn a_failure_on_the_input_is_answered_again_without_running() {
        let jobs = jobs(1, 4);
        let body = serde_json::json!({"function": "1/(x-0.5)", "max_vertices": 100});
        let w = waiter(submit(&jobs, request(body.clone()), Lifetime::WhileWaited).await);
        assert!(matches!(w.job().outcome().await, Outcome::Failed(JobError::Refine(_))));
        // The record replaces the live job once the worker files it.
        tokio::task::yield_now().await;
        for _ in 0..1000 {
            if let Ticket::Failed(_) = submit(&jobs, request(body.clone()), Lifetime::WhileWaited).await {
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
        let w = waiter(submit(&jobs, request(body.clone()), Lifetime::WhileWaited).await);
        w.job().outcome().await;
        jobs.close();
        assert!(matches!(submit(&jobs, request(body), Lifetime::WhileWaited).await, Ticket::Cached(_)));
        let (keys, spec) = request(serde_json::json!({"function": "x-y"}));
        assert_eq!(
            jobs.submit(keys, spec, Lifetime::WhileWaited, &client()).await.err(),
            Some(SubmitError::ShuttingDown)
        );
    }

    #[tokio::test]
    async fn a_smaller_budget_of_a_cached_run_is_replayed_not_run() {
        let jobs = jobs(1, 4);
        let big = serde_json::json!({"function": "exp(x)*sin(3*y)", "max_vertices": 2000});
        let w = waiter(submit(&jobs, request(big), Lifetime::WhileWaited).await);
        w.job().outcome().await;
        let small = serde_json::json!({"function": "exp(x)*sin(3*y)", "max_vertices": 700});
        let Ticket::Prefix(result) = submit(&jobs, request(small), Lifetime::WhileWaited).await else {
            panic!("not a prefix")
        };
        assert_eq!((result.vertices.len(), result.stats.stop()), (700, StopReason::MaxVertices));
        assert_eq!(jobs.metrics().engine_runs.get(), 1);
    }
}
