//! Following a job another replica runs: a local mirror [`Job`] whose state comes from the store,
//! so that clients here wait on it, stream it and fetch its result as if it ran here.
//!
//! One task per mirror ([`keep_current`]) reads the job's stored posting and lease holder at
//! each sweep, and at once when a posting of the job arrives on `meshfit:events`
//! ([`dispatch`] only wakes it): one place decides what a posting means. It follows the run
//! holding the lease, so that a final posting of an earlier run (cancelled, say) is not taken
//! for this one's.

use super::peers::{Control, Kept, Message, Peers, Posting, next_message};
use crate::jobs::Failure;
use crate::jobs::inner::Inner;
use crate::jobs::job::{Job, JobError, Outcome, Record, Status};
use crate::jobs::table::{Started, Waiter};
use crate::refine::StopReason;
use crate::result::Stop;
use crate::result::{RunResult, compact};
use std::sync::{Arc, Weak};
use std::time::Duration;
use tokio::sync::broadcast;

/// How many looks in a row may find the job run nowhere (no lease, not pending for a
/// takeover, no result) before a followed job is given up as lost: its replica died before it
/// could be taken over, or refused the run it had taken the lease for.
const LOST_AFTER: u32 = 3;

/// Attaches a client to this replica's mirror of job `id`, which another replica runs (run
/// `run`, if known), making the mirror (and the task that keeps it current) if there is none.
pub(in crate::jobs) fn follow(inner: &Arc<Inner>, id: String, family: String, run: Option<String>) -> Waiter {
    match inner.table.follow(id, family) {
        Started::Joined(waiter) => waiter,
        Started::New(waiter, job) => {
            inner.metrics.jobs_followed.inc();
            tokio::spawn(keep_current(inner.clone(), job, run));
            waiter
        }
    }
}

/// The record of a job whose posting says it has finished, as clients see it; `None` while
/// it runs.
pub(in crate::jobs) fn record(r: &Posting) -> Option<Record> {
    r.is_final().then(|| view(r))
}

/// A stored posting as clients see it.
pub(in crate::jobs) fn view(r: &Posting) -> Record {
    let status = Status::parse(&r.status).unwrap_or(Status::Queued);
    Record {
        status,
        progress: r.progress,
        stats: r.stats.clone(),
        error: (status == Status::Failed).then(|| failure_of(r)),
        elapsed: r.elapsed_ms.map(|ms| Duration::from_secs_f64(ms / 1e3)),
        last_event: r.seq,
        // Another replica's clock; a posting does not carry it.
        times: None,
    }
}

/// Why the run of a failed posting failed (a posting of an earlier version may not say).
fn failure_of(r: &Posting) -> JobError {
    let said = r.failure.clone();
    JobError::Relayed(
        said.unwrap_or_else(|| Failure::internal("failed on another replica, which did not say why")),
    )
}

/// What a look for a result found.
pub(in crate::jobs) enum Fetched {
    /// The result, now also kept here.
    Found(Arc<RunResult>),
    /// The store answered: it has no such result.
    Missing,
    /// No store, or it did not answer: nothing is known.
    Unreachable,
}

impl Fetched {
    /// The result, if found.
    pub(in crate::jobs) fn found(self) -> Option<Arc<RunResult>> {
        match self {
            Fetched::Found(result) => Some(result),
            _ => None,
        }
    }
}

/// Result `id` from this replica's memory, or else from the store, checked, and kept here from
/// now on. One look per id at a time: the clients of a result just made elsewhere arrive
/// together, and each copy of a large mesh is megabytes.
pub(in crate::jobs) async fn fetch(inner: &Arc<Inner>, id: &str, kept: Kept) -> Fetched {
    // A replica alone has no store to look in, nor a turn to take.
    if !inner.peers.is_shared() {
        return Fetched::Unreachable;
    }
    let turn = inner.fetching.get_with_by_ref(id, Default::default);
    let _turn = turn.lock().await;
    let here = match kept {
        Kept::Whole => inner.cache.get_memory(id),
        Kept::Partial => inner.cache.get_partial(id),
    };
    if let Some(result) = here {
        return Fetched::Found(result);
    }
    let bytes = match inner.peers.result(id, kept).await {
        Ok(Some(bytes)) => bytes,
        Ok(None) => return Fetched::Missing,
        Err(_) => return Fetched::Unreachable,
    };
    let (cache, key) = (inner.cache.clone(), id.to_owned());
    // Checking and decoding a large result, and writing it to the cache directory, is
    // blocking work.
    let read = crate::cpu::spawn(move || {
        let result = Arc::new(compact::read(&bytes, &key).map_err(|e| e.to_string())?);
        match kept {
            Kept::Whole => cache.insert(&key, result.clone()),
            Kept::Partial => cache.insert_partial(&key, result.clone()),
        }
        Ok::<_, String>(result)
    });
    match read.await {
        Ok(Ok(result)) => {
            inner.metrics.shared_hits.inc();
            Fetched::Found(result)
        }
        Ok(Err(why)) => {
            tracing::warn!(id, %why, "discarding a result from redis that does not check");
            Fetched::Missing
        }
        Err(_) => Fetched::Unreachable,
    }
}

/// Applies a running job's posting to its mirror, if newer than what the mirror shows.
fn apply(job: &Job, r: &Posting) {
    let Some(status) = Status::parse(&r.status) else { return };
    job.mirror(r.seq, status, r.progress);
}

/// The outcome of a finished job's posting: its result, or why it failed; `None` while the
/// result cannot be looked for (the store away), to look again later.
async fn outcome(inner: &Arc<Inner>, id: &str, r: &Posting) -> Option<Outcome> {
    Some(match Status::parse(&r.status) {
        Some(Status::Succeeded) => {
            let timed_out = r.stats.as_ref().is_some_and(|s| s.stop() == Stop::Mesh(StopReason::TimeLimit));
            match fetch(inner, id, if timed_out { Kept::Partial } else { Kept::Whole }).await {
                Fetched::Found(result) => Outcome::Succeeded(result),
                // Larger than MESHFIT_REDIS_MAX_BYTES, or expired: only its replica has it.
                Fetched::Missing => Outcome::Failed(JobError::Evicted),
                Fetched::Unreachable => return None,
            }
        }
        Some(Status::Cancelled) => Outcome::Cancelled,
        _ => Outcome::Failed(failure_of(r)),
    })
}

/// What one look at a followed job found.
enum Look {
    /// It finished.
    Finished(Outcome, Option<Duration>),
    /// It is queued or running somewhere, or will be taken over.
    Alive,
    /// No run holds it, none will take it over, and it left no result.
    Nowhere,
    /// The store did not answer.
    Unknown,
}

/// Looks at job `job` in the store, following run `run` (updated to the lease's holder).
async fn look(inner: &Arc<Inner>, peers: &dyn Peers, job: &Job, run: &mut Option<String>) -> Look {
    let Ok(holder) = peers.holder(&job.id).await else { return Look::Unknown };
    if let Some(holder) = &holder {
        *run = Some(holder.clone());
    }
    let Ok(posting) = peers.posting(&job.id).await else { return Look::Unknown };
    // A run leaves its final posting before its lease, so a final posting of the run followed
    // is its end; one of an earlier run is not.
    let ours = |r: &Posting| run.as_ref().is_none_or(|run| *run == r.run);
    match posting {
        Some(r) if ours(&r) && r.is_final() => match outcome(inner, &job.id, &r).await {
            Some(outcome) => {
                Look::Finished(outcome, r.elapsed_ms.map(|ms| Duration::from_secs_f64(ms / 1e3)))
            }
            None => Look::Unknown,
        },
        _ if holder.is_some() => {
            if let Some(r) = posting.filter(ours) {
                apply(job, &r);
            }
            Look::Alive
        }
        // Nobody holds the lease: a sweep takes the job over if it is pending, or it finished
        // and its result is here.
        _ => match peers.is_pending(&job.id).await {
            Ok(true) => Look::Alive,
            Ok(false) => match fetch(inner, &job.id, Kept::Whole).await {
                Fetched::Found(result) => Look::Finished(Outcome::Succeeded(result), None),
                Fetched::Missing => Look::Nowhere,
                Fetched::Unreachable => Look::Unknown,
            },
            Err(_) => Look::Unknown,
        },
    }
}

/// Keeps mirror `job` current until it finishes, then files it like a job run here; or,
/// once nobody has waited on it for two looks, drops it.
async fn keep_current(inner: Arc<Inner>, job: Arc<Job>, mut run: Option<String>) {
    let peers = &*inner.peers;
    let every = peers.sweep_every();
    let (mut told, mut idle, mut lost) = (None, 0, 0);
    loop {
        // A client waits here: the run must not be cancelled when its own clients leave.
        // Told again to each new run (a fresh run drops what was asked of an earlier one).
        if run.is_some() && told != run && peers.control(&job.id, Control::Detach).await.is_ok() {
            told.clone_from(&run);
        }
        match look(&inner, peers, &job, &mut run).await {
            Look::Finished(outcome, elapsed) => {
                job.finish(outcome, elapsed);
                break;
            }
            Look::Alive => lost = 0,
            Look::Nowhere => {
                lost += 1;
                if lost >= LOST_AFTER {
                    let why = format!("job {} is run by no replica; submit it again", job.id);
                    let error = JobError::Internal(why);
                    // Ended for every replica, unless a run has taken the job meanwhile.
                    let posting = super::publish::ended(
                        Status::Failed,
                        None,
                        Some(error.failure()),
                        job.snapshot().seq,
                        "",
                    );
                    let _ = peers.post(&job.id, None, &posting).await;
                    job.finish(Outcome::Failed(error), None);
                    break;
                }
            }
            // The store is away: the clients wait for it to come back, or for their own timeout.
            Look::Unknown => {}
        }
        idle = if inner.table.is_unwatched(&job) { idle + 1 } else { 0 };
        // Checked again under the table's lock, where clients attach: none can be lost.
        if idle >= 2 && inner.table.forget_unwatched(&job) {
            return;
        }
        tokio::select! {
            () = tokio::time::sleep(every) => {}
            () = job.woken() => {}
        }
    }
    inner.table.file(&job);
}

/// Hands every message to the job it concerns on this replica: a posting wakes the mirror's
/// task, a request to cancel or detach goes to the job run here. Ends with the registry.
pub(in crate::jobs) async fn dispatch(inner: Weak<Inner>, mut messages: broadcast::Receiver<Message>) {
    while let Some(message) = next_message(&mut messages).await {
        let Some(inner) = inner.upgrade() else { return };
        let (Message::Posted(id, _) | Message::Control(id, _)) = &message else { continue };
        let Some(job) = inner.table.live(id) else { continue };
        match message {
            Message::Posted(..) if job.follows => job.wake(),
            Message::Control(_, Control::Cancel) if !job.follows => {
                tracing::info!(job = %id, "cancelled from another replica");
                job.cancel();
            }
            Message::Control(_, Control::Detach) if !job.follows => inner.table.detach(&job),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::Cause;

    fn posting(status: &str, failure: Option<Failure>) -> Posting {
        let run = "r".to_owned();
        Posting { status: status.into(), seq: 3, progress: None, stats: None, failure, elapsed_ms: None, run }
    }

    #[test]
    fn a_failed_posting_says_why_even_when_its_writer_did_not() {
        let said = Failure::internal("the refinement panicked");
        let seen = view(&posting("failed", Some(said.clone()))).error.map(|e| e.failure());
        assert_eq!(seen, Some(said));
        // A build from before postings carried failures: an internal failure, not none (which
        // would read as a job whose mesh left the cache).
        let unsaid = record(&posting("failed", None)).expect("final").error.expect("an error");
        assert_eq!(unsaid.failure().cause, Cause::Internal);
        assert!(view(&posting("running", None)).error.is_none());
    }
}
