//! One client job: the points it asked for, the values told, and where it stands. Every
//! change comes as a log [`Entry`], applied in the log's order, so that every replica that
//! applies the same log holds the same job.

use super::log::Entry;
use crate::api::{Evaluations, OnFailure};
use crate::geom::Point;
use crate::refine::asked::{self, Asker, Next, Told, Values};
use crate::result::RunResult;
use crate::spec::ClientSpec;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime};
use tokio::sync::Notify;

/// How long a client job waits for a word from its caller before it expires, and how long a
/// finished one is kept.
pub const CLIENT_IDLE: Duration = Duration::from_secs(3600);

/// One client job.
pub struct ClientJob {
    /// Its id.
    pub id: String,
    spec: ClientSpec,
    state: Mutex<State>,
    /// Where the last replay stopped, for the next to start from; held while one runs.
    asker: Mutex<Asker>,
    /// Held while an entry is written to the log and applied, so that entries are applied
    /// once each and in the log's order.
    pub(super) writer: tokio::sync::Mutex<()>,
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
    /// How many log entries are applied.
    applied: u64,
    /// Whether a replay on this replica is choosing the next batch.
    choosing: bool,
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
        /// What the entry tells (None: failed).
        told: Option<f64>,
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
    /// Job `id` of `spec`, made at `created` with `seeds` (another job's values), having
    /// applied `applied` log entries. Told nothing, it asks for its corners at once; seeded,
    /// its first batch is chosen by a replay, as any next batch.
    pub(super) fn new(
        id: String,
        spec: ClientSpec,
        created: SystemTime,
        seeds: Values,
        applied: u64,
        now: Instant,
    ) -> Self {
        let (points, phase, number) = if seeds.is_empty() {
            match asked::next(spec.rect, &spec.params, &seeds, spec.batch) {
                Ok(Next::Ask(points)) => (points, Phase::Asking, 1),
                _ => unreachable!("a refinement told nothing asks for its corners"),
            }
        } else {
            (Vec::new(), Phase::Choosing, 0)
        };
        let state = State {
            values: seeds,
            told: vec![None; points.len()],
            batch: (0..points.len() as u64).collect(),
            points,
            number,
            lease_until: None,
            phase,
            touched: now,
            failed: 0,
            finished: None,
            applied,
            choosing: false,
        };
        Self {
            id,
            spec,
            state: Mutex::new(state),
            asker: Mutex::new(Asker::default()),
            writer: tokio::sync::Mutex::new(()),
            changed: Notify::new(),
            created,
        }
    }

    /// How many log entries the job has applied: where its next entry goes.
    pub(super) fn applied(&self) -> u64 {
        lock(&self.state).applied
    }

    /// The values told so far, with those it was seeded with.
    pub fn values(&self) -> Values {
        lock(&self.state).values.clone()
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
    pub(super) fn is_stale(&self, now: Instant) -> bool {
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

    /// The entry that tells `values` (id, F or None for a failure), all or none: `None` when
    /// every one was told before (a repeat is a no-op). Apply it to tell them.
    ///
    /// # Errors
    /// An id never asked for, a value that differs from one told before, or a new value for a
    /// finished job.
    pub(super) fn check_tell(
        &self,
        values: &[(u64, Option<f64>)],
        now: Instant,
    ) -> Result<Option<Entry>, TellError> {
        let mut state = self.state(now);
        let finished = state.phase.ended();
        for (index, &(id, value)) in values.iter().enumerate() {
            let Some(told) = state.told.get(id as usize) else {
                return Err(TellError::Unknown { index, id });
            };
            match told {
                Some(was) if same(*was, value) => {}
                Some(was) => return Err(TellError::Conflict { index, id, was: was.value(), told: value }),
                None if finished => return Err(TellError::Finished { index }),
                None => {}
            }
        }
        state.touched = now;
        // The first of an id told twice in one request stands, as a later request's would.
        let mut seen = std::collections::HashSet::new();
        let new: Vec<(u64, Option<f64>)> = (values.iter())
            .filter(|&&(id, _)| state.told[id as usize].is_none() && seen.insert(id))
            .map(|&(id, value)| (id, Told::of(value).value()))
            .collect();
        Ok((!new.is_empty()).then_some(Entry::Told(new)))
    }

    /// Applies log entry `entry`, the next in the log, whoever wrote it.
    pub(super) fn apply(&self, entry: Option<&Entry>, now: Instant) {
        let mut state = self.state(now);
        state.applied += 1;
        match entry {
            // Read when the job was made (`ClientJobs` makes it of them), or from another
            // version: nothing to change.
            None | Some(Entry::Made { .. } | Entry::Seeded(_)) => {}
            Some(Entry::Told(values)) => {
                state.touched = now;
                let mut first_failure = None;
                for &(id, value) in values {
                    let Some(None) = state.told.get(id as usize) else { continue };
                    let told = Told::of(value);
                    state.failed += u64::from(told == Told::Failed);
                    state.told[id as usize] = Some(told);
                    let point = state.points[id as usize];
                    state.values.tell(point, told);
                    if told == Told::Failed && first_failure.is_none() {
                        first_failure = Some((id, point));
                    }
                }
                if let (OnFailure::Fail, Some((id, p)), false) =
                    (self.spec.on_failure, first_failure, state.phase.ended())
                {
                    let detail = format!(
                        "point {id} at ({}, {}) failed, and the job was made to fail on a failed point \
                         (on_failure: fail)",
                        p.x, p.y
                    );
                    state.phase = Phase::Failed(detail);
                    state.finished = Some(SystemTime::now());
                    self.changed.notify_waiters();
                    return;
                }
                let complete = state.batch.iter().all(|&id| state.told[id as usize].is_some());
                if matches!(state.phase, Phase::Asking) && complete {
                    state.phase = Phase::Choosing;
                }
            }
            Some(Entry::Batch { number, points }) => {
                // Chosen here or on another replica: the same points either way.
                if matches!(state.phase, Phase::Choosing) && *number == state.number + 1 {
                    let first = state.points.len() as u64;
                    state.batch = (first..first + points.len() as u64).collect();
                    state.told.extend(points.iter().map(|_| None));
                    state.points.extend(points.iter().map(|&(x, y)| Point::new(x, y)));
                    state.number = *number;
                    state.lease_until = None;
                    state.phase = Phase::Asking;
                    self.changed.notify_waiters();
                }
            }
            Some(Entry::Cancelled) => {
                if !state.phase.ended() {
                    state.phase = Phase::Cancelled;
                    state.finished = Some(SystemTime::now());
                    self.changed.notify_waiters();
                }
                state.touched = now;
            }
        }
    }

    /// Whether batch entry `entry` is the one this job waits for.
    pub(super) fn awaits(&self, entry: &Entry) -> bool {
        let state = lock(&self.state);
        matches!((&state.phase, entry), (Phase::Choosing, Entry::Batch { number, .. }) if *number == state.number + 1)
    }

    /// Marks a replay as choosing the next batch, unless one is or none is needed: whether
    /// the caller is to run it.
    pub(super) fn start_choosing(&self) -> bool {
        let mut state = lock(&self.state);
        let start = matches!(state.phase, Phase::Choosing) && !state.choosing;
        state.choosing |= start;
        start
    }

    /// The replay that chose is over (its batch applied, or not written for now: the next
    /// look at the job starts another).
    pub(super) fn stop_choosing(&self) {
        lock(&self.state).choosing = false;
    }

    /// Chooses the next batch from the values told, a replay of the refinement for the
    /// blocking pool: the batch's entry, for the log; `None` when the mesh is finished (or the
    /// refinement cannot go on), which every replica finds alike from the same values.
    pub(super) fn choose(&self) -> Option<Entry> {
        let mut asker = lock(&self.asker);
        let (values, number) = {
            let state = lock(&self.state);
            if !matches!(state.phase, Phase::Choosing) {
                return None;
            }
            (state.values.clone(), state.number)
        };
        let next = asker.next(self.spec.rect, &self.spec.params, &values, self.spec.batch);
        drop(asker);
        let phase = match next {
            Ok(Next::Ask(points)) => {
                let points = points.iter().map(|p| (p.x, p.y)).collect();
                return Some(Entry::Batch { number: number + 1, points });
            }
            Ok(Next::Done(refinement, _unused)) => Phase::Succeeded(Arc::new(RunResult::from(*refinement))),
            Err(e) => Phase::Failed(e.to_string()),
        };
        let mut state = lock(&self.state);
        if matches!(state.phase, Phase::Choosing) {
            state.phase = phase;
            state.finished = Some(SystemTime::now());
        }
        drop(state);
        self.changed.notify_waiters();
        None
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

    /// The entry that cancels the job, unless it has ended.
    pub(super) fn check_cancel(&self, now: Instant) -> Option<Entry> {
        let mut state = self.state(now);
        state.touched = now;
        (!state.phase.ended()).then_some(Entry::Cancelled)
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

/// Whether `value` says again what `was` said.
fn same(was: Told, value: Option<f64>) -> bool {
    match (was, Told::of(value)) {
        (Told::Value(a), Told::Value(b)) => a == b,
        (Told::Failed, Told::Failed) => true,
        _ => false,
    }
}

/// A lock that a panic elsewhere does not poison for everyone else.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}
