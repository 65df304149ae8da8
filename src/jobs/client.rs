//! Jobs whose F the caller evaluates (ask/tell).
//!
//! A client job holds the points it asked for and the values told, and nothing else between
//! batches: no worker, no engine state, no clock but its lease. When every point of a batch is
//! told, [`choose`](ClientJob::choose) replays the refinement over the values on the blocking
//! pool ([`crate::refine::asked`]) and names the next batch, or finishes the mesh. The mesh
//! depends on the values alone, never on who told them or when.
//!
//! A batch handed out is leased to whoever asked; unanswered past its lease it is offered again
//! to whoever asks next. A job nobody asks or tells for [`CLIENT_IDLE`] expires (a failed job
//! with a problem saying so), and a finished one is dropped that long after its last word.
//! Client jobs live in this replica's memory: another replica does not know them.

use crate::api::Evaluations;
use crate::geom::Point;
use crate::refine::asked::{self, Asker, Next, Told, Values};
use crate::result::RunResult;
use crate::spec::ClientSpec;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime};
use tokio::sync::Notify;

/// The most client jobs a replica keeps, finished ones included.
pub const MAX_CLIENT_JOBS: usize = 256;

/// How long a client job waits for a word from its caller before it expires, and how long a
/// finished one is kept.
pub const CLIENT_IDLE: Duration = Duration::from_secs(3600);

/// The client jobs of this replica.
#[derive(Clone, Default)]
pub struct ClientJobs {
    jobs: Arc<Mutex<HashMap<String, Arc<ClientJob>>>>,
    made: Arc<AtomicU64>,
}

/// Too many client jobs are kept already.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TooManyClientJobs;

impl ClientJobs {
    /// A new client job of `spec`, asking for its corners first.
    ///
    /// # Errors
    /// [`TooManyClientJobs`] when [`MAX_CLIENT_JOBS`] are kept and none has expired.
    pub fn create(&self, spec: ClientSpec, now: Instant) -> Result<Arc<ClientJob>, TooManyClientJobs> {
        let mut jobs = lock(&self.jobs);
        jobs.retain(|_, job| !job.is_stale(now));
        if jobs.len() >= MAX_CLIENT_JOBS {
            return Err(TooManyClientJobs);
        }
        // Not a hash of the request: two callers with the same request run two sessions.
        let made = self.made.fetch_add(1, Ordering::Relaxed);
        let nanos = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).unwrap_or_default().as_nanos();
        let id = format!("{:x}", Sha256::digest(format!("client {made} {nanos} {}", std::process::id())));
        let job = Arc::new(ClientJob::new(id.clone(), spec, now));
        jobs.insert(id, job.clone());
        Ok(job)
    }

    /// Client job `id`, if this replica keeps it.
    pub fn get(&self, id: &str) -> Option<Arc<ClientJob>> {
        lock(&self.jobs).get(id).cloned()
    }
}

/// One client job.
pub struct ClientJob {
    /// Its id.
    pub id: String,
    spec: ClientSpec,
    state: Mutex<State>,
    /// Where the last replay stopped, for the next to start from; held while one runs.
    asker: Mutex<Asker>,
    /// Woken when a batch is chosen or the job ends.
    changed: Notify,
    /// When it was made.
    pub created: SystemTime,
}

/// Where a client job is.
enum Phase {
    /// A batch is out.
    Asking,
    /// Its batch is complete and the next is being chosen.
    Choosing,
    /// Every vertex is told.
    Succeeded(Arc<RunResult>),
    /// The refinement cannot go on, or nobody spoke for [`CLIENT_IDLE`].
    Failed(String),
    /// The caller cancelled it.
    Cancelled,
}

struct State {
    values: Values,
    /// Every point asked for, by id, and what was told of it.
    points: Vec<Point>,
    told: Vec<Option<Told>>,
    /// The ids of the current batch, and its number from 1.
    batch: Vec<u64>,
    number: u64,
    /// Until when the current batch is leased.
    lease_until: Option<Instant>,
    phase: Phase,
    /// The last word from a caller.
    touched: Instant,
    failed: u64,
    finished: Option<SystemTime>,
}

impl Phase {
    /// Whether the job has ended: succeeded, failed or cancelled.
    fn ended(&self) -> bool {
        !matches!(self, Phase::Asking | Phase::Choosing)
    }
}

impl State {
    /// The current batch's points not told yet, by id.
    fn untold(&self) -> Vec<(u64, Point)> {
        (self.batch.iter())
            .filter(|&&id| self.told[id as usize].is_none())
            .map(|&id| (id, self.points[id as usize]))
            .collect()
    }
}

/// What `ask` gives.
#[derive(Debug, Clone, PartialEq)]
pub enum Asked {
    /// Points to evaluate, by id: the current batch's untold ones, leased for `lease`.
    Batch {
        /// The batch's number.
        number: u64,
        /// Its untold points.
        points: Vec<(u64, Point)>,
        /// How long they are the asker's.
        lease: Duration,
    },
    /// Nothing to hand out now: the batch is leased until `until`, or the next is being chosen.
    Wait {
        /// When the lease ends, if one holds the batch.
        until: Option<Instant>,
    },
    /// The job has finished.
    Finished,
}

/// Why values cannot be told.
#[derive(Debug, Clone, PartialEq)]
pub enum TellError {
    /// Entry `index` names a point never asked for.
    Unknown {
        /// The entry.
        index: usize,
        /// Its id.
        id: u64,
    },
    /// Entry `index` differs from what was told of its point before.
    Conflict {
        /// The entry.
        index: usize,
        /// Its id.
        id: u64,
        /// What was told before (None: failed).
        was: Option<f64>,
    },
    /// The job has finished, and the entry is new.
    Finished {
        /// The entry.
        index: usize,
    },
}

/// A job's state as its status shows it.
pub struct ClientStatus {
    /// `running`, `succeeded` or `failed`.
    pub status: &'static str,
    /// The counts.
    pub evaluations: Evaluations,
    /// The mesh, once succeeded.
    pub result: Option<Arc<RunResult>>,
    /// Why it failed.
    pub problem: Option<String>,
    /// When it ended.
    pub finished: Option<SystemTime>,
}

impl ClientJob {
    fn new(id: String, spec: ClientSpec, now: Instant) -> Self {
        // Nothing told: the refinement asks for its corners, without a replay.
        let points = match asked::next(spec.rect, &spec.params, &Values::new(), spec.batch) {
            Ok(Next::Ask(points)) => points,
            _ => unreachable!("a refinement told nothing asks for its corners"),
        };
        let state = State {
            values: Values::new(),
            told: vec![None; points.len()],
            batch: (0..points.len() as u64).collect(),
            points,
            number: 1,
            lease_until: None,
            phase: Phase::Asking,
            touched: now,
            failed: 0,
            finished: None,
        };
        Self {
            id,
            spec,
            state: Mutex::new(state),
            asker: Mutex::new(Asker::default()),
            changed: Notify::new(),
            created: SystemTime::now(),
        }
    }

    /// The state, with a job idle past [`CLIENT_IDLE`] expired first.
    fn state(&self, now: Instant) -> MutexGuard<'_, State> {
        let mut state = lock(&self.state);
        if matches!(state.phase, Phase::Asking) && now.saturating_duration_since(state.touched) > CLIENT_IDLE
        {
            let detail = format!(
                "nobody asked or told for {} s: the job expired after {} of {} points",
                CLIENT_IDLE.as_secs(),
                state.told.iter().flatten().count(),
                state.points.len()
            );
            state.phase = Phase::Failed(detail);
            state.finished = Some(SystemTime::now());
            self.changed.notify_waiters();
        }
        state
    }

    /// Whether the job has ended and nobody spoke to it for [`CLIENT_IDLE`]: it may go.
    fn is_stale(&self, now: Instant) -> bool {
        let state = self.state(now);
        state.phase.ended() && now.saturating_duration_since(state.touched) > CLIENT_IDLE
    }

    /// The number of the latest batch, with its untold points while it is out (leased to
    /// nobody: what an `ask` event announces).
    pub fn current(&self, now: Instant) -> (u64, Option<Vec<(u64, Point)>>) {
        let state = self.state(now);
        (state.number, matches!(state.phase, Phase::Asking).then(|| state.untold()))
    }

    /// Whether the job has ended, one way or another.
    pub fn is_finished(&self, now: Instant) -> bool {
        self.state(now).phase.ended()
    }

    /// How long a batch handed out is leased.
    pub fn lease(&self) -> Duration {
        self.spec.lease
    }

    /// The current batch's untold points, leased to the asker, when no lease holds them.
    pub fn ask(&self, now: Instant) -> Asked {
        let mut state = self.state(now);
        match state.phase {
            Phase::Asking => {}
            Phase::Choosing => return Asked::Wait { until: None },
            Phase::Succeeded(_) | Phase::Failed(_) | Phase::Cancelled => return Asked::Finished,
        }
        state.touched = now;
        if let Some(until) = state.lease_until.filter(|&until| until > now) {
            return Asked::Wait { until: Some(until) };
        }
        state.lease_until = Some(now + self.spec.lease);
        Asked::Batch { number: state.number, points: state.untold(), lease: self.spec.lease }
    }

    /// Tells `values` (id, F or None for a failure), all or none: how many were new, and
    /// whether they completed the batch (then [`choose`](Self::choose) must run).
    ///
    /// # Errors
    /// An id never asked for, a value that differs from one told before, or a new value for a
    /// finished job.
    pub fn tell(&self, values: &[(u64, Option<f64>)], now: Instant) -> Result<(u64, bool), TellError> {
        let mut state = self.state(now);
        let finished = state.phase.ended();
        for (index, &(id, value)) in values.iter().enumerate() {
            let Some(told) = state.told.get(id as usize) else {
                return Err(TellError::Unknown { index, id });
            };
            match told {
                Some(was) if same(*was, value) => {}
                Some(was) => {
                    let was = match was {
                        Told::Value(v) => Some(*v),
                        Told::Failed => None,
                    };
                    return Err(TellError::Conflict { index, id, was });
                }
                None if finished => return Err(TellError::Finished { index }),
                None => {}
            }
        }
        state.touched = now;
        let mut accepted = 0;
        for &(id, value) in values {
            if state.told[id as usize].is_some() {
                continue;
            }
            let told = to_told(value);
            state.failed += u64::from(told == Told::Failed);
            state.told[id as usize] = Some(told);
            let point = state.points[id as usize];
            state.values.tell(point, told);
            accepted += 1;
        }
        let complete = matches!(state.phase, Phase::Asking)
            && state.batch.iter().all(|&id| state.told[id as usize].is_some());
        if complete {
            state.phase = Phase::Choosing;
        }
        Ok((accepted, complete))
    }

    /// Chooses the next batch, or finishes the mesh, from the values told: a replay of the
    /// refinement, for the blocking pool.
    pub fn choose(&self) {
        let mut asker = lock(&self.asker);
        let values = lock(&self.state).values.clone();
        let next = asker.next(self.spec.rect, &self.spec.params, &values, self.spec.batch);
        drop(asker);
        let mut state = lock(&self.state);
        if !matches!(state.phase, Phase::Choosing) {
            return;
        }
        match next {
            Ok(Next::Ask(points)) => {
                let first = state.points.len() as u64;
                state.batch = (first..first + points.len() as u64).collect();
                state.told.extend(points.iter().map(|_| None));
                state.points.extend(points);
                state.number += 1;
                state.lease_until = None;
                state.phase = Phase::Asking;
            }
            Ok(Next::Done(refinement, _unused)) => {
                state.phase = Phase::Succeeded(Arc::new(RunResult::from(*refinement)));
                state.finished = Some(SystemTime::now());
            }
            Err(e) => {
                state.phase = Phase::Failed(e.to_string());
                state.finished = Some(SystemTime::now());
            }
        }
        drop(state);
        self.changed.notify_waiters();
    }

    /// Choosing the next batch broke off (a panic): the job fails, rather than wait for a
    /// batch that never comes.
    pub fn choosing_failed(&self, detail: String) {
        let mut state = lock(&self.state);
        if matches!(state.phase, Phase::Choosing) {
            state.phase = Phase::Failed(detail);
            state.finished = Some(SystemTime::now());
        }
        drop(state);
        self.changed.notify_waiters();
    }

    /// Cancels the job unless it has finished: it asks for nothing more.
    pub fn cancel(&self, now: Instant) {
        let mut state = self.state(now);
        if !state.phase.ended() {
            state.phase = Phase::Cancelled;
            state.finished = Some(SystemTime::now());
        }
        state.touched = now;
        drop(state);
        self.changed.notify_waiters();
    }

    /// Resolves once the job may have something new for an asker: enable it before asking,
    /// so that a change in between is not missed.
    pub fn changed(&self) -> tokio::sync::futures::Notified<'_> {
        self.changed.notified()
    }

    /// The job's state as its status shows it.
    pub fn status(&self, now: Instant) -> ClientStatus {
        let state = self.state(now);
        let told = state.told.iter().flatten().count() as u64;
        let pending = state.batch.iter().filter(|&&id| state.told[id as usize].is_none()).count() as u64;
        let evaluations =
            Evaluations { asked: state.points.len() as u64, told, pending, failed: state.failed };
        let (status, result, problem) = match &state.phase {
            Phase::Asking | Phase::Choosing => ("running", None, None),
            Phase::Succeeded(result) => ("succeeded", Some(result.clone()), None),
            Phase::Failed(detail) => ("failed", None, Some(detail.clone())),
            Phase::Cancelled => ("cancelled", None, None),
        };
        ClientStatus { status, evaluations, result, problem, finished: state.finished }
    }
}

/// What a tell's value says of its point: a number, or a failure (null, or not finite).
fn to_told(value: Option<f64>) -> Told {
    match value {
        Some(v) if v.is_finite() => Told::Value(v),
        _ => Told::Failed,
    }
}

/// Whether `value` says again what `was` said.
fn same(was: Told, value: Option<f64>) -> bool {
    match (was, to_told(value)) {
        (Told::Value(a), Told::Value(b)) => a == b,
        (Told::Failed, Told::Failed) => true,
        _ => false,
    }
}

/// A lock that a panic elsewhere does not poison for everyone else.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}
