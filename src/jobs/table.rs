//! The job table: which jobs this replica holds, live or finished, and who waits on them.
//!
//! Like mini-redis's `Db`, the table owns its state: its map is private, its lock is taken
//! only inside its own methods, and a function that must run under the lock takes the guard
//! ([`Locked`]). Callers ask (`join`, `start`, `follow`, `file`, `cancel_all`, …); none reaches
//! in. A job's clients are counted under this lock (see [`TableLock`]).

use super::job::{Job, Lifetime, Record, TableLock};
use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};

/// How many finished job records are kept for status queries (results live in the cache).
const FINISHED_KEPT: usize = 10_000;

/// The job table.
pub(super) struct Table {
    /// A std Mutex: held only for map operations, never across an `.await`.
    map: Mutex<Map>,
}

#[derive(Default)]
struct Map {
    jobs: HashMap<String, Listing>,
    /// Finished jobs' ids, oldest first: the records kept.
    finished: VecDeque<String>,
}

/// The table under its lock: held only for map operations, never across an `.await`.
struct Locked<'a>(MutexGuard<'a, Map>);

impl TableLock for Locked<'_> {}

/// What the table holds for a job id.
#[derive(Clone)]
pub(super) enum Listing {
    /// A job queued or running (or just finished, until it is filed).
    Live(Arc<Job>),
    /// A finished job's record.
    Done(Arc<Record>),
}

/// What the table answers to an identical request.
pub(super) enum Joined {
    /// The live job, with the client registered as waiting on it.
    Job(Waiter),
    /// The record of the job once run.
    Done(Arc<Record>),
}

/// What a start or a follow came to.
pub(super) enum Started {
    /// An identical live job was joined instead.
    Joined(Waiter),
    /// The new job, listed, with the client registered as waiting on it.
    New(Waiter, Arc<Job>),
}

/// A client waiting on a job. When the last one leaves a job that nobody detached, the job is
/// cancelled: a synchronous request or stream whose client hung up.
pub struct Waiter {
    job: Arc<Job>,
    table: Arc<Table>,
}

impl Waiter {
    /// The job waited on.
    pub fn job(&self) -> &Arc<Job> {
        &self.job
    }
}

impl Drop for Waiter {
    fn drop(&mut self) {
        let table = self.table.lock();
        if self.job.leave(&table) {
            tracing::info!(job = %self.job.id, "last client left; cancelling");
            self.job.cancel();
        }
    }
}

/// Drops the oldest finished records past [`FINISHED_KEPT`].
fn prune(jobs: &mut HashMap<String, Listing>, finished: &mut VecDeque<String>) {
    while finished.len() > FINISHED_KEPT {
        let oldest = finished.pop_front().expect("non-empty");
        if matches!(jobs.get(&oldest), Some(Listing::Done(_))) {
            jobs.remove(&oldest);
        }
    }
}

impl Table {
    /// An empty table.
    pub(super) fn new() -> Arc<Self> {
        Arc::new(Self { map: Mutex::new(Map::default()) })
    }

    fn lock(&self) -> Locked<'_> {
        Locked(self.map.lock().expect("job table poisoned"))
    }

    /// Registers a client waiting on `job`, under the table's lock: a waiter's drop decides
    /// under the same lock whether it was the last, so no client can be lost in between.
    fn attach(self: &Arc<Self>, table: &Locked<'_>, job: &Arc<Job>, lifetime: Lifetime) -> Waiter {
        job.attach(table);
        if lifetime == Lifetime::Detached {
            job.detach(table);
        }
        Waiter { job: job.clone(), table: self.clone() }
    }

    /// What the table holds for `id`.
    pub(super) fn get(&self, id: &str) -> Option<Listing> {
        self.lock().0.jobs.get(id).cloned()
    }

    /// The live job `id`, if any.
    pub(super) fn live(&self, id: &str) -> Option<Arc<Job>> {
        match self.lock().0.jobs.get(id) {
            Some(Listing::Live(job)) => Some(job.clone()),
            _ => None,
        }
    }

    /// Joins live job `id` for `lifetime` if it may be joined, or gives its record; `None` for
    /// a job being cancelled (a new one starts) or one unknown here.
    pub(super) fn join(self: &Arc<Self>, id: &str, lifetime: Lifetime) -> Option<Joined> {
        let table = self.lock();
        match table.0.jobs.get(id)? {
            Listing::Live(job) if job.is_joinable() => Some(Joined::Job(self.attach(&table, job, lifetime))),
            Listing::Done(record) => Some(Joined::Done(record.clone())),
            Listing::Live(_) => None,
        }
    }

    /// Registers a client waiting on live job `id` while it runs; else the record of job
    /// `id`, if finished here.
    pub(super) fn watch(self: &Arc<Self>, id: &str) -> Result<Waiter, Option<Arc<Record>>> {
        let table = self.lock();
        match table.0.jobs.get(id) {
            Some(Listing::Live(job)) => Ok(self.attach(&table, job, Lifetime::WhileWaited)),
            Some(Listing::Done(record)) => Err(Some(record.clone())),
            None => Err(None),
        }
    }

    /// Joins the live job `id` if it may be joined (a job followed from elsewhere gives way
    /// to a run of this replica holding the lease: `leased`), else lists the job `make` gives
    /// (or its error), all under the lock, so that two identical starts make one job.
    pub(super) fn start<E>(
        self: &Arc<Self>,
        id: &str,
        lifetime: Lifetime,
        leased: bool,
        make: impl FnOnce() -> Result<Arc<Job>, E>,
    ) -> Result<Started, E> {
        let mut table = self.lock();
        if let Some(Listing::Live(job)) = table.0.jobs.get(id)
            && job.is_joinable()
            && !(leased && job.follows)
        {
            return Ok(Started::Joined(self.attach(&table, job, lifetime)));
        }
        let job = make()?;
        let waiter = self.attach(&table, &job, lifetime);
        table.0.jobs.insert(id.to_owned(), Listing::Live(job.clone()));
        Ok(Started::New(waiter, job))
    }

    /// Registers a client on this replica's mirror of job `id`, which another replica runs:
    /// the live one if it may be joined, else a new one (listed unless a run of this replica
    /// still ending holds the id's place, where shutdown and the sweep look for it; the
    /// mirror then lives on for its clients alone).
    pub(super) fn follow(self: &Arc<Self>, id: String, family: String) -> Started {
        let mut table = self.lock();
        let live = match table.0.jobs.get(&id) {
            Some(Listing::Live(job)) if job.is_joinable() => {
                return Started::Joined(self.attach(&table, job, Lifetime::WhileWaited));
            }
            Some(Listing::Live(_)) => true,
            _ => false,
        };
        // Detached: a client leaving here never cancels the job; `DELETE` does, through the
        // store. Its family is unknown here; a mirror notes no runs for replays.
        let job = Arc::new(Job::new(id.clone(), family, Lifetime::Detached, true, 0));
        let waiter = self.attach(&table, &job, Lifetime::WhileWaited);
        if !live {
            table.0.jobs.insert(id, Listing::Live(job.clone()));
        }
        Started::New(waiter, job)
    }

    /// Keeps `record` for `id` unless the table holds something for it: a result answered from
    /// the cache, so that the job list and `GET /v1/jobs/{id}` know it without reading the
    /// cache again. Counted among the finished records kept.
    pub(super) fn remember(&self, id: &str, record: Record) {
        let mut table = self.lock();
        let Map { jobs, finished } = &mut *table.0;
        if !jobs.contains_key(id) {
            jobs.insert(id.to_owned(), Listing::Done(Arc::new(record)));
            finished.push_back(id.to_owned());
            prune(jobs, finished);
        }
    }

    /// Replaces a finished job's table entry with its record (waiting clients hold the job,
    /// and its mesh, until they have read it), keeping at most [`FINISHED_KEPT`] records.
    pub(super) fn file(&self, job: &Arc<Job>) {
        let record = Arc::new(Record::of(&job.snapshot()));
        let mut table = self.lock();
        let Map { jobs, finished } = &mut *table.0;
        if matches!(jobs.get(&job.id), Some(Listing::Live(j)) if Arc::ptr_eq(j, job)) {
            jobs.insert(job.id.clone(), Listing::Done(record));
            finished.push_back(job.id.clone());
        }
        prune(jobs, finished);
    }

    /// Whether no client waits on `job`.
    pub(super) fn is_unwatched(&self, job: &Job) -> bool {
        job.is_unwatched(&self.lock())
    }

    /// Drops `job` from the table (if listed) when no client waits on it; says whether it
    /// did. Clients attach under the lock, so none can be lost in between.
    pub(super) fn forget_unwatched(&self, job: &Arc<Job>) -> bool {
        let mut table = self.lock();
        if !job.is_unwatched(&table) {
            return false;
        }
        if matches!(table.0.jobs.get(&job.id), Some(Listing::Live(j)) if Arc::ptr_eq(j, job)) {
            table.0.jobs.remove(&job.id);
        }
        true
    }

    /// Lets `job` run to its end whoever waits.
    pub(super) fn detach(&self, job: &Job) {
        job.detach(&self.lock());
    }

    /// Whether this replica runs job `id` now (rather than following it, or not having it).
    pub(super) fn runs_here(&self, id: &str) -> bool {
        let table = self.lock();
        matches!(table.0.jobs.get(id), Some(Listing::Live(job)) if !job.follows && !job.is_finished())
    }

    /// Stops every job run here and not yet finished, for shutdown (see
    /// [`Job::stop_for_shutdown`]); a job followed from another replica runs on there.
    pub(super) fn stop_all(&self) {
        for entry in self.lock().0.jobs.values() {
            if let Listing::Live(job) = entry
                && !job.follows
            {
                job.stop_for_shutdown();
            }
        }
    }

    /// Whether any job run here is queued or running (a job followed from another replica
    /// is that replica's to finish).
    pub(super) fn is_busy(&self) -> bool {
        self.lock().0.jobs.values().any(|e| matches!(e, Listing::Live(job) if !job.follows))
    }
}

#[cfg(test)]
mod tests {
    //! The table alone: no registry, no worker; each test makes its jobs by hand.

    use super::*;
    use crate::jobs::Outcome;
    use std::convert::Infallible;

    fn job(id: &str, lifetime: Lifetime) -> Arc<Job> {
        Arc::new(Job::new(id.to_owned(), id.to_owned(), lifetime, false, 0))
    }

    /// Starts job `id` for `lifetime`, unleased: the new job, or the one joined.
    fn start(table: &Arc<Table>, id: &str, lifetime: Lifetime) -> (Waiter, bool) {
        match table.start::<Infallible>(id, lifetime, false, || Ok(job(id, lifetime))).unwrap() {
            Started::New(waiter, _) => (waiter, true),
            Started::Joined(waiter) => (waiter, false),
        }
    }

    #[test]
    fn the_last_client_leaving_cancels_a_job_nobody_detached() {
        let table = Table::new();
        let (first, new) = start(&table, "a", Lifetime::WhileWaited);
        let (second, joined) = start(&table, "a", Lifetime::WhileWaited);
        assert!(new && !joined, "the second start joins the first job");
        assert!(Arc::ptr_eq(first.job(), second.job()));
        let job = first.job().clone();
        drop(first);
        assert!(!job.is_cancelled(), "a client still waits");
        drop(second);
        assert!(job.is_cancelled());
        assert!(table.join("a", Lifetime::WhileWaited).is_none(), "a cancelled job is not joined");
    }

    #[test]
    fn a_detached_client_keeps_the_job_going_after_everyone_leaves() {
        let table = Table::new();
        let (waiting, _) = start(&table, "a", Lifetime::WhileWaited);
        let Some(Joined::Job(detached)) = table.join("a", Lifetime::Detached) else { panic!("not joined") };
        let job = waiting.job().clone();
        drop((waiting, detached));
        assert!(!job.is_cancelled());
        assert!(table.runs_here("a") && table.is_busy());
    }

    #[test]
    fn a_filed_job_leaves_its_record_and_its_clients_keep_the_outcome() {
        let table = Table::new();
        let (waiter, _) = start(&table, "a", Lifetime::WhileWaited);
        waiter.job().finish(Outcome::Cancelled, None);
        table.file(waiter.job());
        assert!(!table.is_busy());
        let Some(Listing::Done(record)) = table.get("a") else { panic!("no record") };
        assert_eq!(record.status, crate::jobs::Status::Cancelled);
        assert_eq!(waiter.job().snapshot().status, crate::jobs::Status::Cancelled);
    }

    #[test]
    fn a_mirror_gives_way_to_a_leased_run_and_is_not_listed_over_a_run_still_ending() {
        let table = Table::new();
        let Started::New(follower, mirror) = table.follow("a".into(), "a".into()) else { panic!("joined") };
        assert!(mirror.follows && !table.runs_here("a"));
        // A run of this replica that took the lease replaces the mirror in the table.
        let leased = table
            .start::<Infallible>("a", Lifetime::WhileWaited, true, || Ok(job("a", Lifetime::WhileWaited)));
        let Ok(Started::New(running, run)) = leased else { panic!("the mirror was joined") };
        assert!(table.runs_here("a") && !Arc::ptr_eq(&run, &mirror));
        // Cancelled and still ending: a new mirror is made, and the run keeps its place.
        run.cancel();
        let Started::New(_again, other) = table.follow("a".into(), "a".into()) else { panic!("joined") };
        assert!(matches!(table.get("a"), Some(Listing::Live(j)) if Arc::ptr_eq(&j, &run)));
        assert!(!table.forget_unwatched(&other), "its client waits");
        drop((follower, running));
        assert!(table.forget_unwatched(&mirror), "nobody waits on the first mirror");
        assert!(table.live("a").is_some_and(|j| Arc::ptr_eq(&j, &run)), "the run was not dropped for it");
    }
}
