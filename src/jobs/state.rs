//! The job table and what every part of the registry shares: the table's lock, the queue's
//! count, the cache, the families, the other replicas, and the helpers that read
//! or change the table under its lock.

use super::Cache;
use super::budget::Budget;
use super::dispatch::Dispatch;
use super::job::{Job, JobError, Lifetime, Record, Status};
use super::replica::peers::{KeptRequest, Peers};
use super::share::Shares;
use crate::metrics::Metrics;
use crate::result::MeshResult;
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

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
        let _table = self.inner.lock();
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

/// How many finished job records are kept for status queries (results live in the cache).
pub(super) const FINISHED_KEPT: usize = 10_000;

pub(super) struct Inner {
    pub(super) dispatch: Arc<Dispatch>,
    pub(super) workers: usize,
    pub(super) queue: usize,
    /// Jobs created and not yet holding a worker (some of which will get one at once).
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
    /// The other replicas: [`Alone`](super::replica::peers::Alone) until the registry is
    /// [`shared`](super::Jobs::shared).
    pub(super) peers: Arc<dyn Peers>,
    /// A turn per result being read from the store (see `follow::fetch`).
    pub(super) fetching: moka::sync::Cache<String, Arc<tokio::sync::Mutex<()>>>,
    /// Jobs whose state is still being told to the store: shutdown waits for them too, so that a
    /// job handed back gives up its lease before the process ends.
    pub(super) publishing: AtomicUsize,
}

/// A new job's id, family and place among the replicas.
pub(super) struct Start {
    pub(super) id: String,
    pub(super) family: String,
    /// Its events are numbered after this (a job taken over continues the numbering).
    pub(super) seq: u64,
    /// The lease this replica holds for the job, if replicas share: the run then publishes
    /// the job's state.
    pub(super) lease: Option<Lease>,
    /// The request, to keep in the store for a takeover.
    pub(super) request: Option<KeptRequest>,
}

/// A run's lease on a job.
pub(super) struct Lease {
    /// The run's token, as the lease holds it.
    pub(super) token: String,
    /// Told once the run's first posting is stored.
    pub(super) announced: Option<tokio::sync::oneshot::Sender<()>>,
}

pub(super) enum Listing {
    Live(Arc<Job>),
    Done(Arc<Record>),
}

impl Job {
    /// Lets the job run to its end whoever waits. Under the table's lock, like every change
    /// of it: a waiter's drop reads it under the lock.
    pub(super) fn detach(&self, _table: &Locked<'_>) {
        self.detached.store(true, Ordering::SeqCst);
    }
}

/// The job table under its lock: held only for map operations, never across an `.await`.
pub(super) type Locked<'a> = std::sync::MutexGuard<'a, Table>;

#[derive(Default)]
pub(super) struct Table {
    pub(super) jobs: HashMap<String, Listing>,
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

    /// Whether this replica runs job `id` now (rather than following it, or not having it).
    pub(super) fn runs_here(&self, id: &str) -> bool {
        let table = self.lock();
        matches!(table.jobs.get(id), Some(Listing::Live(job)) if !job.follows && !job.is_finished())
    }

    /// Jobs waiting beyond the free workers: the queue proper.
    pub(super) fn queued(&self) -> usize {
        self.waiting.load(Ordering::SeqCst).saturating_sub(self.dispatch.free())
    }

    /// Whether one more job would wait at most behind `queue` others: it either finds a free
    /// worker or a place in the queue.
    pub(super) fn has_room(&self) -> bool {
        self.waiting.load(Ordering::SeqCst) < self.queue + self.dispatch.free()
    }

    /// Seconds until one of `lanes` busy workers is likely free, at the mean time a job has
    /// taken: the `Retry-After` of a refusal, at least 1 s and at most an hour.
    pub(super) fn retry_after(&self, lanes: usize) -> u64 {
        let mean = f64::from_bits(self.mean_run.load(Ordering::Relaxed));
        (mean / lanes.max(1) as f64).ceil().clamp(1.0, 3600.0) as u64
    }

    /// Folds a job's run time into the mean (weight 1/8: a few jobs move it, one does not).
    pub(super) fn note_run_time(&self, seconds: f64) {
        let _ = self.mean_run.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |bits| {
            Some((f64::from_bits(bits) + (seconds - f64::from_bits(bits)) / 8.0).to_bits())
        });
    }

    /// Answers from the table under its lock: joins a live job, repeats a failure on the
    /// input, or finds a result cached since the caller's lookup.
    pub(super) fn join(self: &Arc<Self>, id: &str, lifetime: Lifetime) -> Option<Ticket> {
        let table = self.lock();
        match table.jobs.get(id)? {
            Listing::Live(job) if job.is_joinable() => {
                self.metrics.cache_misses.inc();
                Some(Ticket::Job(self.attach(&table, job, lifetime)))
            }
            Listing::Done(record) => match &record.error {
                // A failure on the input is deterministic: it is the answer again.
                Some(e @ JobError::Refine(_)) => {
                    self.metrics.cache_misses.inc();
                    Some(Ticket::Failed(e.clone()))
                }
                // It may have been cached between the lookup and the lock.
                _ if record.status == Status::Succeeded => {
                    let finished = self.cache.get_memory(id)?;
                    self.metrics.cache_hits.inc();
                    Some(Ticket::Cached(finished))
                }
                // Cancelled, an internal error, or a mesh evicted from the cache: run again.
                _ => None,
            },
            // A job being cancelled: start a new one.
            Listing::Live(_) => None,
        }
    }

    /// Replaces a finished job's table entry with its record (waiting clients hold the job,
    /// and its mesh, until they have read it), keeping at most [`FINISHED_KEPT`] records.
    pub(super) fn file(&self, job: &Arc<Job>) {
        let record = Arc::new(Record::of(&job.snapshot()));
        let mut table = self.lock();
        if matches!(table.jobs.get(&job.id), Some(Listing::Live(j)) if Arc::ptr_eq(j, job)) {
            table.jobs.insert(job.id.clone(), Listing::Done(record));
            table.finished.push_back(job.id.clone());
        }
        while table.finished.len() > FINISHED_KEPT {
            let oldest = table.finished.pop_front().expect("non-empty");
            if matches!(table.jobs.get(&oldest), Some(Listing::Done(_))) {
                table.jobs.remove(&oldest);
            }
        }
    }

    /// Registers a client waiting on `job`, under the table's lock: a waiter's drop decides
    /// under the same lock whether it was the last, so no client can be lost in between.
    pub(super) fn attach(self: &Arc<Self>, table: &Locked<'_>, job: &Arc<Job>, lifetime: Lifetime) -> Waiter {
        job.waiters.fetch_add(1, Ordering::SeqCst);
        if lifetime == Lifetime::Detached {
            job.detach(table);
        }
        Waiter { job: job.clone(), inner: self.clone() }
    }

    /// The job table, locked. Functions that must run under the lock take the guard.
    pub(super) fn lock(&self) -> Locked<'_> {
        self.table.lock().expect("job table poisoned")
    }
}
