//! Following a job another replica runs: a local mirror [`Job`] whose state comes from Redis,
//! so that clients here wait on it, stream it and fetch its result as if it ran here.
//!
//! The mirror is kept current twice over: by the records every replica receives on
//! `meshfit:events` ([`dispatch`]), and by reading the stored record at each sweep
//! ([`keep_current`]), which catches what a dropped subscription missed and is the one place
//! a mirror finishes.

use super::job::{Job, JobError, Outcome, Record, Status};
use super::registry::{Entry, Inner, Waiter};
use crate::cluster::{self, Control, Message};
use crate::refine::StopReason;
use crate::result::{MeshResult, compact};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Weak};
use std::time::Duration;
use tokio::sync::broadcast;

/// How many looks in a row may find no record, no lease and no result before a followed job
/// is given up as lost (its replica died before it kept the request).
const LOST_AFTER: u32 = 3;

/// Attaches a client to this replica's mirror of job `id`, which another replica runs,
/// making the mirror (and the task that keeps it current) if there is none.
pub(super) fn follow(inner: &Arc<Inner>, id: String, family: String) -> Waiter {
    let mut table = inner.table.lock().expect("job table poisoned");
    if let Some(Entry::Live(job)) = table.jobs.get(&id)
        && job.is_joinable()
    {
        return inner.attach(job, false);
    }
    // Detached: a client leaving here never cancels the job; `DELETE` does, through Redis.
    let job = Arc::new(Job::new(id.clone(), family, true, true, 0));
    let waiter = inner.attach(&job, false);
    table.jobs.insert(id, Entry::Live(job.clone()));
    drop(table);
    inner.metrics.jobs_followed.inc();
    tokio::spawn(keep_current(inner.clone(), job));
    waiter
}

/// The record of a job that has finished, as clients see it; `None` while it runs.
pub(super) fn record(r: &cluster::Record) -> Option<Record> {
    if !r.is_final() {
        return None;
    }
    let status = Status::parse(&r.status)?;
    let error = r.problem.clone().map(JobError::Relayed);
    Some(Record {
        status,
        progress: r.progress,
        stats: r.stats.clone(),
        error,
        elapsed: r.elapsed_ms.map(|ms| Duration::from_secs_f64(ms / 1e3)),
    })
}

/// Result `id` from Redis, checked, and kept here from now on; `None` without Redis or
/// without the result.
pub(super) async fn fetch(inner: &Arc<Inner>, id: &str, partial: bool) -> Option<Arc<MeshResult>> {
    let bytes = inner.shared.as_ref()?.cluster.result(id, partial).await.ok()??;
    let (cache, key) = (inner.cache.clone(), id.to_owned());
    // Checking and decoding a large result, and writing it to the cache directory, is
    // blocking work.
    let read = crate::cpu::spawn(move || {
        let result = Arc::new(compact::read(&bytes, &key).map_err(|e| e.to_string())?);
        match partial {
            true => cache.insert_partial(&key, result.clone()),
            false => cache.insert(&key, result.clone()),
        }
        Ok::<_, String>(result)
    });
    match read.await {
        Ok(Ok(result)) => {
            inner.metrics.shared_hits.inc();
            Some(result)
        }
        Ok(Err(why)) => {
            tracing::warn!(id, %why, "discarding a result from redis that does not check");
            None
        }
        Err(_) => None,
    }
}

/// Applies a running job's record to its mirror, if newer than what the mirror shows.
fn apply(job: &Job, r: &cluster::Record) {
    let Some(status) = Status::parse(&r.status) else { return };
    job.state.send_if_modified(|s| {
        let newer = s.outcome.is_none() && (r.seq > s.seq || (r.seq == s.seq && s.status != status));
        if newer {
            (s.seq, s.status, s.progress) = (r.seq, status, r.progress.or(s.progress));
        }
        newer
    });
}

/// The outcome of a finished job's record: its result fetched from Redis, or its problem.
async fn outcome(inner: &Arc<Inner>, id: &str, r: &cluster::Record) -> Outcome {
    match Status::parse(&r.status) {
        Some(Status::Succeeded) => {
            let partial = r.stats.as_ref().is_some_and(|s| s.stop() == StopReason::TimeLimit);
            // This replica may have run it itself, having taken it over.
            let here = match partial {
                true => inner.cache.get_partial(id),
                false => inner.cache.get_memory(id),
            };
            let found = match here {
                Some(result) => Some(result),
                None => fetch(inner, id, partial).await,
            };
            match found {
                Some(result) => Outcome::Succeeded(result),
                // Larger than MESHFIT_REDIS_MAX_BYTES, or expired: only its replica has it.
                None => Outcome::Failed(JobError::Evicted),
            }
        }
        Some(Status::Cancelled) => Outcome::Cancelled,
        _ => Outcome::Failed(r.problem.clone().map_or_else(
            || JobError::Internal(format!("job {id} failed on another replica without a problem")),
            JobError::Relayed,
        )),
    }
}

/// Keeps mirror `job` current until it finishes, or until nobody has waited on it for two
/// looks, then files it like a job run here.
async fn keep_current(inner: Arc<Inner>, job: Arc<Job>) {
    let Some(shared) = &inner.shared else { return };
    let cluster = &shared.cluster;
    // A client waits here: the job's own replica must not cancel it when its clients leave.
    let _ = cluster.control(&job.id, Control::Detach).await;
    let every = super::takeover::sweep_every(cluster.settings().lease);
    let (mut idle, mut lost) = (0, 0);
    loop {
        match cluster.record(&job.id).await {
            Ok(Some(r)) if r.is_final() => {
                let outcome = outcome(&inner, &job.id, &r).await;
                job.finish(outcome, r.elapsed_ms.map(|ms| Duration::from_secs_f64(ms / 1e3)));
                break;
            }
            Ok(Some(r)) => {
                lost = 0;
                apply(&job, &r);
            }
            Ok(None) => match (cluster.is_leased(&job.id).await, fetch(&inner, &job.id, false).await) {
                (_, Some(result)) => {
                    job.finish(Outcome::Succeeded(result), None);
                    break;
                }
                (Ok(false), None) => {
                    lost += 1;
                    if lost >= LOST_AFTER {
                        let why = format!("job {} is no longer known to any replica", job.id);
                        job.finish(Outcome::Failed(JobError::Internal(why)), None);
                        break;
                    }
                }
                // Queued on a replica that has not stored its record yet, or Redis is away.
                _ => {}
            },
            // Redis is away: the clients wait for it to come back, or for their own timeout.
            Err(_) => {}
        }
        idle = if job.waiters.load(Ordering::SeqCst) == 0 { idle + 1 } else { 0 };
        if idle >= 2 {
            let mut table = inner.table.lock().expect("job table poisoned");
            if matches!(table.jobs.get(&job.id), Some(Entry::Live(j)) if Arc::ptr_eq(j, &job)) {
                table.jobs.remove(&job.id);
            }
            return;
        }
        // A final record wakes this loop at once (see `dispatch`).
        tokio::select! {
            () = tokio::time::sleep(every) => {}
            () = job.cancel_notify.notified() => {}
        }
    }
    inner.file(&job);
}

/// Hands every message to the job it concerns on this replica: records to mirrors, requests
/// to cancel or detach to jobs run here. Ends with the registry.
pub(super) async fn dispatch(inner: Weak<Inner>, mut messages: broadcast::Receiver<Message>) {
    loop {
        let message = match messages.recv().await {
            Ok(m) => m,
            // Missed records are read back by `keep_current`.
            Err(broadcast::error::RecvError::Lagged(_)) => continue,
            Err(broadcast::error::RecvError::Closed) => return,
        };
        let Some(inner) = inner.upgrade() else { return };
        let (id, job) = match &message {
            Message::Record(id, _) | Message::Control(id, _) => {
                let table = inner.table.lock().expect("job table poisoned");
                match table.jobs.get(id) {
                    Some(Entry::Live(job)) => (id, job.clone()),
                    _ => continue,
                }
            }
            Message::Subscribed => continue,
        };
        match message {
            Message::Record(_, r) if job.follows => match r.is_final() {
                // Fetching the result is for `keep_current`, which finishes the mirror.
                true => job.cancel_notify.notify_one(),
                false => apply(&job, &r),
            },
            Message::Control(_, Control::Cancel) if !job.follows => {
                tracing::info!(job = %id, "cancelled from another replica");
                job.cancel();
            }
            Message::Control(_, Control::Detach) if !job.follows => {
                // Under the lock, like every change of `detached` (see `Waiter`'s drop).
                let _table = inner.table.lock().expect("job table poisoned");
                job.detached.store(true, Ordering::SeqCst);
            }
            _ => {}
        }
    }
}
