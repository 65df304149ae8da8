//! The registry: [`Jobs`], the one public face of the jobs: submit, find, watch, cancel, shut
//! down. Each part it is made of owns its state (see [`Inner`]); what a submission does, step
//! by step, is in `submit`.

use super::admission::{Admission, Pool, SubmitError};
use super::budget::Budget;
use super::families::Families;
use super::history::{History, Submission};
use super::inner::Inner;
use super::job::{Job, Lifetime, Record, Status};
use super::replica::peers::{self, Alone, Control, Kept, Peers};
use super::replica::{follow, takeover};
use super::share::Client;
use super::table::{Listing, Table, Waiter};
use super::ticket::Ticket;
use super::{Cache, submit};
use crate::metrics::Metrics;
use crate::result::RunResult;
use crate::spec::{JobKeys, JobSpec, Limits};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::SystemTime;

/// A job, a finished job's record, or a cached result, for status queries.
#[derive(Clone)]
pub enum Found {
    /// A job queued or running (or just finished, while clients still read its outcome).
    Job(Arc<Job>),
    /// A finished job.
    Done(Arc<Record>),
    /// A result from the cache with no job record (e.g. after a restart).
    Cached(Arc<RunResult>),
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

/// How many results being read from the store keep their turn (see [`follow::fetch`]).
const FETCHES_KEPT: u64 = 10_000;

/// The job registry, its workers and its cache. Cheap to clone.
#[derive(Clone)]
pub struct Jobs {
    inner: Arc<Inner>,
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
                history: History::new(pool.job_retention),
                publishing: AtomicUsize::new(0),
            }),
        }
    }

    /// Shares results and jobs with the other replicas through `peers`, in place of the
    /// store-less `peers::Alone`; the specs of jobs taken over are held to `limits`, this
    /// replica's. Call it before the registry is cloned, from within the runtime.
    ///
    /// # Panics
    /// When the registry has been cloned.
    #[must_use]
    pub fn shared(mut self, peers: Arc<dyn Peers>, limits: Limits) -> Self {
        let inner = Arc::get_mut(&mut self.inner).expect("shared before the registry is cloned");
        let messages = peers.messages();
        inner.peers = peers;
        tokio::spawn(follow::dispatch(Arc::downgrade(&self.inner), messages));
        tokio::spawn(takeover::sweep(Arc::downgrade(&self.inner), limits));
        self
    }

    /// Whether replicas share through the store, and if so whether the store answered last.
    pub fn redis(&self) -> Option<bool> {
        let peers = &self.inner.peers;
        peers.is_shared().then(|| peers.is_up())
    }

    /// The store this replica shares with others (`peers::Alone`'s, that fails every
    /// operation, for a replica on its own).
    pub fn peers(&self) -> Arc<dyn Peers> {
        self.inner.peers.clone()
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
    /// `client`, to run for `lifetime`. When replicas share through the store, a job this
    /// replica runs keeps its spec there, so that another replica can take it over, and a job
    /// another replica runs is followed rather than run again.
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
        let id = keys.id.clone();
        let ticket = submit::submit(&self.inner, keys, spec, lifetime, client).await?;
        if let Ticket::Cached(result) | Ticket::Prefix(result) = &ticket {
            self.inner.table.remember(&id, Record::cached(result));
        }
        self.inner.history.note(&id, client, SystemTime::now());
        Ok(ticket)
    }

    /// Notes that `client` made a job this registry does not run (a client job, which the
    /// caller evaluates), so that the list shows it in its place.
    pub fn note_submission(&self, id: &str, client: &Client) {
        self.inner.history.note(id, client, SystemTime::now());
    }

    /// The jobs submitted to this replica, newest first: of `client` alone when given, with
    /// `status` when given, numbered below `before` (the cursor); at most `limit`, and the
    /// cursor of the next page when more are left. Each job as this replica's table holds it
    /// (never a read of the cache or the store), or, with `None`, one the table does not hold
    /// whose status `elsewhere` knows (a client job); a job neither knows is left out.
    pub fn list(
        &self,
        client: Option<&Client>,
        status: Option<Status>,
        before: Option<u64>,
        limit: usize,
        elsewhere: impl Fn(&str) -> Option<Status>,
    ) -> (Vec<(Submission, Option<Record>)>, Option<u64>) {
        let mut page = Vec::new();
        for submission in self.inner.history.newest(client, before, SystemTime::now()) {
            let record = match self.inner.table.get(&submission.id) {
                Some(Listing::Live(job)) => Some(Record::of(&job.snapshot())),
                Some(Listing::Done(record)) => Some((*record).clone()),
                None => None,
            };
            let Some(its) = record.as_ref().map(|r| r.status).or_else(|| elsewhere(&submission.id)) else {
                continue;
            };
            if status.is_some_and(|s| s != its) {
                continue;
            }
            if page.len() == limit {
                let next = page.last().map(|(s, _): &(Submission, Option<Record>)| s.seq);
                return (page, next);
            }
            page.push((submission, record));
        }
        (page, None)
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
    pub async fn partial(&self, id: &str) -> Option<Arc<RunResult>> {
        match self.inner.cache.get_partial(id) {
            Some(result) => Some(result),
            None => follow::fetch(&self.inner, id, Kept::Partial).await.found(),
        }
    }

    /// The cached mesh with this id, if any.
    pub async fn cached(&self, id: &str) -> Option<Arc<RunResult>> {
        submit::cached(&self.inner, id).await
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
    use crate::jobs::{JobError, Outcome};
    use crate::refine::StopReason;
    use crate::spec::job_keys;
    use std::num::NonZeroUsize;
    use std::time::Duration;

    fn jobs(workers: usize, queue: usize) -> Jobs {
        let cache = Cache::new(64 << 20, None, 0).unwrap();
        let workers = NonZeroUsize::new(workers).unwrap();
        let pool = Pool {
            workers,
            queue,
            client_share: 1.0,
            memory_bytes: 8 << 30,
            job_retention: Duration::from_secs(3600),
        };
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
        assert_eq!(
            (result.vertices.len(), result.stats.stop()),
            (700, crate::result::Stop::Mesh(StopReason::MaxVertices))
        );
        assert_eq!(jobs.metrics().engine_runs.get(), 1);
    }
}
