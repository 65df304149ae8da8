//! The job record: a job's status, progress and outcome, and the one view of them clients get.

use super::Failure;
use crate::api::ProgressEvent;
use crate::geom::Vertex;
use crate::refine::RefineError;
use crate::result::RunResult;
use crate::result::Summary;
use crate::solve::SolveError;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};
use tokio::sync::{Notify, watch};

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

    /// The status named `name` in the API.
    pub fn parse(name: &str) -> Option<Self> {
        [Status::Queued, Status::Running, Status::Succeeded, Status::Failed, Status::Cancelled]
            .into_iter()
            .find(|s| s.as_str() == name)
    }
}

/// Why a job failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JobError {
    /// The engine refused the input (F not finite at a point).
    #[error(transparent)]
    Refine(RefineError),
    /// The solver failed: on the problem (k ≤ 0 where it sampled it, say), or on a mesh it
    /// cannot use (see [`Failure`]'s causes).
    #[error(transparent)]
    Solve(SolveError),
    /// Something went wrong inside the server; the detail is logged, not sent.
    #[error("internal error: {0}")]
    Internal(String),
    /// The job succeeded, but its mesh has since left the cache.
    #[error("the mesh is no longer cached")]
    Evicted,
    /// Shutdown stopped the job here and handed it to another replica: its clients should ask
    /// again (any replica will follow it there).
    #[error("handed to another replica at shutdown")]
    HandedBack,
    /// The job failed on another replica, which stored why.
    #[error("failed on another replica: {}", .0.message)]
    Relayed(Failure),
}

impl JobError {
    /// The failure as clients are told it, whichever replica they ask. [`JobError::Evicted`]
    /// and [`JobError::HandedBack`] are not failures of a run (the server answers them in its
    /// own terms); they read as internal.
    pub fn failure(&self) -> Failure {
        match self {
            JobError::Refine(e) => e.into(),
            JobError::Solve(e) => e.into(),
            JobError::Internal(message) => Failure::internal(message.clone()),
            JobError::Evicted | JobError::HandedBack => Failure::internal(self.to_string()),
            JobError::Relayed(failure) => failure.clone(),
        }
    }
}

/// How a job ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// With a mesh.
    Succeeded(Arc<RunResult>),
    /// With an error.
    Failed(JobError),
    /// Cancelled by a client, by every waiting client leaving, or by shutdown (of a replica
    /// with no other to hand the job to: see [`JobError::HandedBack`]).
    Cancelled,
}

/// A job's state as watchers see it. `seq` counts the job's server-sent events (each progress
/// report, then the outcome), so events carry it as their id, 1, 2, 3, …, and a reconnecting
/// client can skip what it has seen.
#[derive(Debug, Clone)]
pub struct Snapshot {
    /// Events so far: one per progress report, and one for the outcome.
    pub seq: u64,
    /// Where the job is.
    pub status: Status,
    /// The latest progress report.
    pub progress: Option<ProgressEvent>,
    /// Set once finished.
    pub outcome: Option<Outcome>,
    /// How long the engine ran, once finished.
    pub elapsed: Option<Duration>,
    /// When the job was made, a worker took it, and it ended.
    pub times: Times,
}

/// When a job was made, a worker took it (none for a job cancelled while queued, or one
/// another replica runs), and it ended. Wall-clock times, for people: never a scheduling
/// input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Times {
    /// Made on this replica (or followed from another).
    pub created: SystemTime,
    /// A worker took it.
    pub started: Option<SystemTime>,
    /// It ended.
    pub finished: Option<SystemTime>,
}

/// How long a submitted job runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lifetime {
    /// While a client waits on it: the last one leaving cancels it (a synchronous request or
    /// an event stream whose client hung up).
    WhileWaited,
    /// To its end, whoever waits (`POST /v1/jobs`).
    Detached,
}

/// What the job table's lock guard alone implements (`table::Locked`): a job's clients are
/// counted under that lock, so that a client leaving and one joining cannot both decide
/// whether the job goes on. The methods that count them take the guard: the rule is a type.
pub(super) trait TableLock {}

/// What a job has been asked to stop for. One atomic, set once by the first request (a
/// client's cancel, or shutdown's), read by the engine at every insertion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Stop {
    /// Not asked to stop.
    Go = 0,
    /// Cancelled: by a client, by every waiting client leaving, or by shutdown of a replica
    /// with no other to take the job over.
    Cancel = 1,
    /// Stopped by shutdown and handed back: its lease is given up unfinished, so that another
    /// replica takes it over, instead of telling its clients it was cancelled.
    HandBack = 2,
}

/// One refinement, shared by everyone waiting on it.
///
/// Its lifecycle ([`Status`]: queued, running, then succeeded, failed or cancelled) changes
/// only through its own methods (`run`, `report`, `finish`, and `mirror` for a job followed
/// from another replica), and its clients only through the table's. Its state and progress
/// go through a watch channel, not atomics: the latest snapshot wins, and SSE clients read
/// it at their own pace. Three things stay atomic, each for a stated reason: the stop
/// request, read at every insertion of the engine's hot loop, where no lock may be taken;
/// the client count and the detached flag, guarded by the table's lock, which lives outside
/// the job (the methods that change them take its guard, see `TableLock`); and the kept
/// flag, set once by the task that publishes the job.
pub struct Job {
    /// Set at creation, never changed.
    pub(super) id: String,
    /// The id of the requests whose runs are prefixes of this one's (see [`crate::spec::JobKeys`]).
    /// Set at creation, never changed.
    pub(super) family: String,
    /// Whether another replica runs the job and this one follows it through the store. Set at
    /// creation, never changed.
    pub(super) follows: bool,
    /// The latest state wins: a slow watcher skips snapshots and the worker never waits on it
    /// (a watch channel, not a queue).
    state: watch::Sender<Snapshot>,
    /// A [`Stop`]: an atomic, because the engine reads it at every insertion and must not
    /// take a lock there.
    stop: AtomicU8,
    /// Wakes the task waiting for the job's worker (or, for a followed job, its next look) when
    /// it is stopped or has news.
    wake: Notify,
    /// Created through `POST /v1/jobs`: runs on even when no client is waiting. Changed and
    /// read under the table lock, like `waiters` (see [`TableLock`]).
    detached: AtomicBool,
    /// Clients waiting on the job (see [`TableLock`]).
    waiters: AtomicUsize,
    /// A running mesh job's vertices as of its latest progress report, in insertion order,
    /// for viewers that follow the mesh as it grows; emptied when the job finishes (the
    /// result has them all).
    points: Mutex<Vec<Vertex>>,
    /// Whether its request is kept in the store, so that another replica can take it over:
    /// set once by the task publishing it, read when shutdown stops the job.
    kept: AtomicBool,
}

impl Job {
    /// A queued job whose events are numbered after `seq` (a job taken over from another
    /// replica continues that replica's numbering).
    pub(super) fn new(id: String, family: String, lifetime: Lifetime, follows: bool, seq: u64) -> Self {
        let (state, _) = watch::channel(Snapshot {
            seq,
            status: Status::Queued,
            progress: None,
            outcome: None,
            elapsed: None,
            times: Times { created: SystemTime::now(), started: None, finished: None },
        });
        Self {
            id,
            family,
            follows,
            state,
            stop: AtomicU8::new(Stop::Go as u8),
            wake: Notify::new(),
            detached: AtomicBool::new(lifetime == Lifetime::Detached),
            waiters: AtomicUsize::new(0),
            points: Mutex::new(Vec::new()),
            kept: AtomicBool::new(false),
        }
    }

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

    /// Vertices `from..to` of the mesh as it grows, as far as they are held: a progress report
    /// that counts n vertices comes after the first n are here, until the job finishes.
    pub fn points(&self, from: usize, to: usize) -> Vec<Vertex> {
        let points = self.points.lock().expect("job points poisoned");
        points.get(from..to.min(points.len())).map_or_else(Vec::new, <[Vertex]>::to_vec)
    }

    /// Asks the job to stop: a queued job ends at once, a running one within one insertion.
    /// A job already asked to stop keeps what was asked first.
    pub fn cancel(&self) {
        self.ask(Stop::Cancel);
        self.wake.notify_one();
    }

    /// Stops the job for shutdown: handed back for another replica to take over when its
    /// request is kept in the store, else cancelled. Decided once per job: a job already asked
    /// to stop (by a client, or by an earlier call) keeps what was decided.
    pub(super) fn stop_for_shutdown(&self) {
        if self.ask(if self.kept.load(Ordering::SeqCst) { Stop::HandBack } else { Stop::Cancel }) {
            self.wake.notify_one();
        }
    }

    /// Asks the job to stop for `stop` unless it was asked already; says whether this asked.
    fn ask(&self, stop: Stop) -> bool {
        self.stop.compare_exchange(Stop::Go as u8, stop as u8, Ordering::SeqCst, Ordering::Relaxed).is_ok()
    }

    /// Whether the job was asked to stop, either way: what the engine reads at each insertion.
    pub(super) fn is_cancelled(&self) -> bool {
        self.stop.load(Ordering::Relaxed) != Stop::Go as u8
    }

    /// Whether shutdown stopped the job to hand it to another replica.
    pub(super) fn is_handed_back(&self) -> bool {
        self.stop.load(Ordering::SeqCst) == Stop::HandBack as u8
    }

    /// Notes that the job's request is kept in the store: shutdown hands it back from now on.
    pub(super) fn mark_kept(&self) {
        self.kept.store(true, Ordering::SeqCst);
    }

    /// Wakes whoever waits on [`woken`](Self::woken): a followed job's task, to look again.
    pub(super) fn wake(&self) {
        self.wake.notify_one();
    }

    /// Completes when the job is asked to stop or [woken](Self::wake).
    pub(super) fn woken(&self) -> tokio::sync::futures::Notified<'_> {
        self.wake.notified()
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

    pub(super) fn is_finished(&self) -> bool {
        self.state.borrow().outcome.is_some()
    }

    /// Whether a new identical request may join this job instead of starting its own.
    pub(super) fn is_joinable(&self) -> bool {
        !self.is_cancelled() && !self.is_finished()
    }

    /// Queued → running: a worker took the job.
    pub(super) fn run(&self) {
        self.state.send_modify(|s| {
            s.status = Status::Running;
            s.times.started = Some(SystemTime::now());
        });
    }

    /// A progress report, numbered as the next event; `vertices`, a mesh's vertices so far
    /// (the first ones as already held), for viewers.
    pub(super) fn report(&self, vertices: Option<&[Vertex]>, event: ProgressEvent) {
        if let Some(vertices) = vertices {
            let mut points = self.points.lock().expect("job points poisoned");
            let held = points.len();
            points.extend_from_slice(&vertices[held..]);
        }
        self.state.send_modify(|s| {
            s.seq += 1;
            s.progress = Some(event);
        });
    }

    /// Applies what the run of a followed job last posted (its event number, status and
    /// progress), if newer than what this mirror shows.
    pub(super) fn mirror(&self, seq: u64, status: Status, progress: Option<ProgressEvent>) {
        self.state.send_if_modified(|s| {
            let newer = s.outcome.is_none() && (seq > s.seq || (seq == s.seq && s.status != status));
            if newer {
                (s.seq, s.status, s.progress) = (seq, status, progress.or(s.progress));
            }
            newer
        });
    }

    /// Ends the job: its outcome, numbered as the next event; the vertices held for viewers
    /// are let go.
    pub(super) fn finish(&self, outcome: Outcome, elapsed: Option<Duration>) {
        *self.points.lock().expect("job points poisoned") = Vec::new();
        self.state.send_modify(|s| {
            s.seq += 1;
            s.elapsed = elapsed;
            s.times.finished = Some(SystemTime::now());
            s.status = match outcome {
                Outcome::Succeeded(_) => Status::Succeeded,
                Outcome::Failed(_) => Status::Failed,
                Outcome::Cancelled => Status::Cancelled,
            };
            s.outcome = Some(outcome);
        });
    }

    /// Registers one more client waiting on the job.
    pub(super) fn attach(&self, _table: &impl TableLock) {
        self.waiters.fetch_add(1, Ordering::Relaxed);
    }

    /// Lets the job run to its end whoever waits.
    pub(super) fn detach(&self, _table: &impl TableLock) {
        self.detached.store(true, Ordering::Relaxed);
    }

    /// A client stops waiting; says whether the job should be cancelled: it was the last, the
    /// job is not detached, and it has not finished.
    pub(super) fn leave(&self, _table: &impl TableLock) -> bool {
        let last = self.waiters.fetch_sub(1, Ordering::Relaxed) == 1;
        last && !self.detached.load(Ordering::Relaxed) && !self.is_finished()
    }

    /// Whether the job runs to its end whoever waits: for tests, which read it without the
    /// table's lock, as a condition to wait for.
    #[cfg(test)]
    pub(super) fn is_detached(&self) -> bool {
        self.detached.load(Ordering::SeqCst)
    }

    /// Whether no client waits on the job.
    pub(super) fn is_unwatched(&self, _table: &impl TableLock) -> bool {
        self.waiters.load(Ordering::Relaxed) == 0
    }
}

/// The one view of a job's state that clients are given, whatever holds the job: a live job's
/// snapshot, the table's record of a finished job (never its mesh, which lives only in the
/// byte-bounded cache), or a cached result.
#[derive(Debug, Clone)]
pub struct Record {
    /// Where the job is.
    pub status: Status,
    /// The last progress report.
    pub progress: Option<ProgressEvent>,
    /// The stats, when succeeded.
    pub stats: Option<Summary>,
    /// The error, when failed.
    pub error: Option<JobError>,
    /// How long the engine ran.
    pub elapsed: Option<Duration>,
    /// The id of the job's last server-sent event: its final event once it has finished; 0
    /// where that is not known (a result found in the cache alone).
    pub last_event: u64,
    /// When the job was made, started and ended, where this replica saw it.
    pub times: Option<Times>,
}

impl Record {
    /// The view of a live job's snapshot.
    pub fn of(snapshot: &Snapshot) -> Self {
        let (stats, error) = match &snapshot.outcome {
            Some(Outcome::Succeeded(f)) => (Some(f.stats.clone()), None),
            Some(Outcome::Failed(e)) => (None, Some(e.clone())),
            _ => (None, None),
        };
        Self {
            status: snapshot.status,
            progress: snapshot.progress,
            stats,
            error,
            elapsed: snapshot.elapsed,
            last_event: snapshot.seq,
            times: Some(snapshot.times),
        }
    }

    /// The view of a job whose run has taken its lease on another replica and not yet told
    /// anything more.
    pub fn queued() -> Self {
        Self {
            status: Status::Queued,
            progress: None,
            stats: None,
            error: None,
            elapsed: None,
            last_event: 0,
            times: None,
        }
    }

    /// The view of a result found in the cache with no job record (e.g. after a restart).
    pub fn cached(result: &RunResult) -> Self {
        Self {
            status: Status::Succeeded,
            progress: None,
            stats: Some(result.stats.clone()),
            error: None,
            elapsed: None,
            last_event: 0,
            times: None,
        }
    }
}
