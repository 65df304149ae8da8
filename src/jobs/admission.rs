//! Admission: whether a new job may start here, and its place until a worker takes it. One
//! type holds everything a scheduler weighs: whether the server is open, the queue and its
//! bound, each [`Client`]'s share (from `share`), the workers handed out by `dispatch`, the
//! memory [`Budget`], and the mean run time every `Retry-After` is made from.

use super::budget::{Budget, Charge};
use super::dispatch::{Dispatch, Worker};
use super::share::{Client, Seat, Shares};
use std::num::NonZeroUsize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

/// What a server runs jobs with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pool {
    /// Refinements running at once (`MESHFIT_WORKERS`).
    pub workers: NonZeroUsize,
    /// Jobs that may wait for a worker beyond them (`MESHFIT_QUEUE`).
    pub queue: usize,
    /// One client's share of the workers and the queue, in (0, 1] (`MESHFIT_CLIENT_SHARE`).
    pub client_share: f64,
    /// The memory budget that jobs, bodies and cached meshes are charged to
    /// (`MESHFIT_MEMORY_BYTES`).
    pub memory_bytes: u64,
    /// How long `GET /v1/jobs` lists a submission (`MESHFIT_JOB_RETENTION_MS`).
    pub job_retention: std::time::Duration,
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

/// Who may start a job here, and who runs next.
pub(super) struct Admission {
    /// Set once at shutdown: no new job from then on.
    closed: AtomicBool,
    workers: usize,
    /// Jobs that may wait beyond the free workers.
    queue: usize,
    /// Jobs admitted and not yet holding a worker (some of which will get one at once).
    waiting: AtomicUsize,
    dispatch: Arc<Dispatch>,
    shares: Shares,
    budget: Arc<Budget>,
    /// The mean time a job ran, in seconds (f64 bits; a moving average): the basis of every
    /// `Retry-After`.
    mean_run: AtomicU64,
}

/// An admitted job's place: its seat in its client's share and its memory, held until
/// dropped (when the job ends).
pub(super) struct Admitted {
    seat: Seat,
    // Held for its drop.
    _memory: Charge,
}

impl Admission {
    /// The admission of `pool`, whose memory budget also counts the bytes `held` reports
    /// (the cache's meshes).
    pub(super) fn new(pool: &Pool, held: impl Fn() -> u64 + Send + Sync + 'static) -> Self {
        let Pool { workers, queue, client_share, memory_bytes, .. } = *pool;
        let workers = workers.get();
        let shares = Shares::new(client_share, workers, queue);
        Self {
            closed: AtomicBool::new(false),
            workers,
            queue,
            waiting: AtomicUsize::new(0),
            dispatch: Dispatch::new(workers, shares.workers),
            shares,
            budget: Budget::new(memory_bytes, held),
            mean_run: AtomicU64::new(1f64.to_bits()),
        }
    }

    /// The memory budget that bodies and jobs are charged to.
    pub(super) fn budget(&self) -> &Arc<Budget> {
        &self.budget
    }

    /// Refuses new jobs from now on.
    pub(super) fn close(&self) {
        self.closed.store(true, Ordering::SeqCst);
    }

    /// Whether new jobs are refused.
    pub(super) fn is_closed(&self) -> bool {
        self.closed.load(Ordering::SeqCst)
    }

    /// Whether a new job would be accepted now.
    pub(super) fn is_ready(&self) -> bool {
        !self.is_closed() && self.has_room()
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

    /// Seconds until a worker, and the memory its job holds, is likely free: the
    /// `Retry-After` of a refusal.
    pub(super) fn retry_after(&self) -> u64 {
        self.retry_after_lanes(self.workers)
    }

    /// Seconds until one of `lanes` busy workers is likely free, at the mean time a job has
    /// taken: at least 1 s and at most an hour.
    fn retry_after_lanes(&self, lanes: usize) -> u64 {
        let mean = f64::from_bits(self.mean_run.load(Ordering::Relaxed));
        (mean / lanes.max(1) as f64).ceil().clamp(1.0, 3600.0) as u64
    }

    /// The refusal of a job that found the queue full.
    pub(super) fn queue_full(&self) -> SubmitError {
        SubmitError::QueueFull { waiting: self.queued(), retry_after: self.retry_after() }
    }

    /// Admits a job of `client` that holds `bytes` of memory, in this order: the server is
    /// open, the queue has room, the client is within its share, the budget holds it. The job
    /// waits (counted in the queue) until [`worker`](Self::worker) gives it one.
    pub(super) fn admit(&self, client: &Client, bytes: u64) -> Result<Admitted, SubmitError> {
        if self.is_closed() {
            return Err(SubmitError::ShuttingDown);
        }
        if !self.has_room() {
            return Err(self.queue_full());
        }
        let seat = self.shares.charge(client).map_err(|held| SubmitError::ShareUsed {
            held,
            retry_after: self.retry_after_lanes(self.shares.workers),
        })?;
        let memory = self.budget.charge(bytes).map_err(|over| SubmitError::OverBudget {
            needed: over.needed,
            available: over.available,
            retry_after: self.retry_after(),
        })?;
        self.waiting.fetch_add(1, Ordering::SeqCst);
        Ok(Admitted { seat, _memory: memory })
    }

    /// A worker for admitted job `admitted`, in the order `dispatch` decides, or `None` when
    /// `stopped` completes first (the job was cancelled while it waited). The job leaves the
    /// queue either way.
    pub(super) async fn worker(
        &self,
        admitted: &Admitted,
        stopped: impl Future<Output = ()>,
    ) -> Option<Worker> {
        let worker = tokio::select! {
            worker = self.dispatch.acquire(admitted.seat.client()) => worker,
            () = stopped => None,
        };
        self.waiting.fetch_sub(1, Ordering::SeqCst);
        worker
    }

    /// Folds a job's run time into the mean (weight 1/8: a few jobs move it, one does not).
    pub(super) fn note_run_time(&self, seconds: f64) {
        let _ = self.mean_run.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |bits| {
            Some((f64::from_bits(bits) + (seconds - f64::from_bits(bits)) / 8.0).to_bits())
        });
    }

    /// Takes a worker, as a job would: tests hold every worker to keep jobs queued, and so
    /// decide when the engine runs.
    #[cfg(test)]
    pub(super) async fn hold_worker(&self) -> Worker {
        let client = Client::from("test:holder".to_owned());
        self.dispatch.acquire(&client).await.expect("a worker")
    }
}
