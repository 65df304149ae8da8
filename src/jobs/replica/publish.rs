//! The run holding a shared job's lease tells the other replicas about it: keeps its spec
//! for a takeover, stores its posting as it changes (at most every [`PUBLISH_EVERY`]), renews
//! its lease and reads what followers ask of it, and at the end stores the result before the
//! final posting, so that a replica that reads the posting can fetch the result.

use super::lease::Lease;
use super::peers::{Acquired, Asked, Kept, Peers, Posting, Take};
use crate::jobs::Failure;
use crate::jobs::inner::Inner;
use crate::jobs::job::{Job, JobError, Outcome, Snapshot, Status};
use crate::refine::StopReason;
use crate::result::Stop;
use crate::result::{RunResult, Summary, compact};
use crate::source::Source;
use crate::spec::{JobSpec, canonical};
use std::sync::Arc;
use std::time::Duration;
use tokio::time::Instant;

/// Postings go out at most this often while a job runs; the final one at once.
const PUBLISH_EVERY: Duration = Duration::from_millis(100);

/// Publishes job `job` for run `lease` until it finishes.
pub(in crate::jobs) async fn run(inner: &Arc<Inner>, job: Arc<Job>, lease: Lease, to_keep: Option<JobSpec>) {
    let (peers, token) = (&*inner.peers, lease.token.as_str());
    let mut rx = job.subscribe();
    // The first posting first: the submission's client waits for it, and a large spec
    // would keep it waiting.
    // (A job that has ended already gets its final posting from `finish` alone.)
    let first = rx.borrow_and_update().clone();
    if first.outcome.is_none() {
        let _ = peers.post(&job.id, Some(token), &wire(&first, None, token)).await;
    }
    let mut sent = Some((first.seq, first.status));
    let mut last = Some(Instant::now());
    if let Some(announced) = lease.announced {
        let _ = announced.send(());
    }
    match to_keep {
        Some(spec) => match renewing(peers, &job.id, token, keep_spec(peers, &job.id, spec)).await {
            Ok(true) => job.mark_kept(),
            _ => {
                tracing::info!(job = %job.id, "spec not kept in redis: no other replica can take this job over")
            }
        },
        // A job taken over: its spec is kept already.
        None => job.mark_kept(),
    }
    let mut renew = tokio::time::interval(peers.renew_every());
    renew.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    renew.tick().await;
    loop {
        let snapshot = rx.borrow_and_update().clone();
        if snapshot.outcome.is_some() {
            return finish(inner, peers, &job, token, &snapshot).await;
        }
        let fresh = sent != Some((snapshot.seq, snapshot.status));
        let due = last.map(|t| t + PUBLISH_EVERY).filter(|_| fresh);
        if fresh && due.is_none_or(|due| Instant::now() >= due) {
            let _ = peers.post(&job.id, Some(token), &wire(&snapshot, None, token)).await;
            (sent, last) = (Some((snapshot.seq, snapshot.status)), Some(Instant::now()));
            continue;
        }
        let wait = async {
            match due {
                Some(due) => tokio::time::sleep_until(due).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            changed = rx.changed() => if changed.is_err() { return },
            () = wait => {}
            _ = renew.tick() => keep(inner, peers, &job, token).await,
        }
    }
}

/// Keeps job `id`'s `spec` in the store for a takeover. A grid's encoding, 8 bytes a
/// sample, is made on the blocking pool; any other is a few hundred bytes, made here.
async fn keep_spec(peers: &dyn Peers, id: &str, spec: JobSpec) -> super::peers::Result<bool> {
    let bytes = if spec.mesh().is_some_and(|m| matches!(*m.source, Source::Grid(_))) {
        match crate::cpu::spawn(move || canonical::encode(&spec)).await {
            Ok(bytes) => bytes,
            Err(_) => return Ok(false),
        }
    } else {
        canonical::encode(&spec)
    };
    peers.keep_spec(id, &bytes).await
}

/// Awaits `work` while renewing run `token`'s lease. Sending a large spec,
/// or encoding and storing a large result, can take longer than a lease: a job whose lease
/// lapsed before it was listed as pending would look to its followers as if it ran nowhere,
/// and one whose lease lapsed at its end would be taken over and run again.
async fn renewing<T>(peers: &dyn Peers, id: &str, token: &str, work: impl Future<Output = T>) -> T {
    let mut work = std::pin::pin!(work);
    let every = peers.renew_every();
    let mut renew = tokio::time::interval_at(Instant::now() + every, every);
    loop {
        tokio::select! {
            done = &mut work => return done,
            _ = renew.tick() => {
                let _ = peers.renew(id, token).await;
            }
        }
    }
}

/// Renews run `token`'s lease, taking it again if it lapsed while the store was away, and acts on
/// what followers asked of the run.
async fn keep(inner: &Inner, peers: &dyn Peers, job: &Job, token: &str) {
    if let Ok(false) = peers.renew(&job.id, token).await
        && let Ok(Acquired::Held(_)) = peers.acquire(&job.id, token, Take::Over).await
    {
        // Another replica took the job over meanwhile: both runs make the same bytes, and
        // only the holder's postings are written, so this one goes on quietly.
        tracing::warn!(job = %job.id, "lease lost to another replica");
    }
    if let Ok(Asked { cancel, detach }) = peers.asked(&job.id).await {
        if cancel {
            job.cancel();
        }
        if detach {
            inner.table.detach(job);
        }
    }
}

/// How long a finished run keeps trying to tell the store of its end while the store is away.
const DELIVER_FOR: Duration = Duration::from_secs(600);

/// Stores the result and the final posting, takes the job off the pending list and gives up
/// the lease; a job handed back at shutdown only gives up its lease, for a takeover. While
/// the store is away this is tried again at each sweep, so that a job that finished during an
/// outage is known to every replica once the store is back.
async fn finish(inner: &Arc<Inner>, peers: &dyn Peers, job: &Job, token: &str, snapshot: &Snapshot) {
    let (failure, result) = match snapshot.outcome.as_ref().expect("finished") {
        Outcome::Failed(JobError::HandedBack) => {
            tracing::info!(job = %job.id, "handed back for another replica to take over");
            let _ = peers.release(&job.id, token).await;
            return;
        }
        // Renewed meanwhile: encoding and storing a large result can outlast a short lease,
        // and a follower would then take the job over and run it again.
        Outcome::Succeeded(result) => (None, renewing(peers, &job.id, token, encode(&job.id, result)).await),
        Outcome::Failed(e) => (Some(e.failure()), None),
        Outcome::Cancelled => (None, None),
    };
    let posting = wire(snapshot, failure, token);
    let give_up = Instant::now() + DELIVER_FOR;
    while !renewing(peers, &job.id, token, deliver(peers, &job.id, token, result.as_ref(), &posting)).await {
        if inner.admission.is_closed() || Instant::now() >= give_up {
            tracing::warn!(job = %job.id, "redis away: other replicas will not know this job finished");
            return;
        }
        tokio::time::sleep(peers.sweep_every()).await;
    }
}

/// A result in compact form, and how the store keeps it (partial when a time limit stopped
/// its run).
async fn encode(id: &str, result: &Arc<RunResult>) -> Option<(Vec<u8>, Kept)> {
    let kept = match result.stats.stop() {
        Stop::Mesh(StopReason::TimeLimit) => Kept::Partial,
        _ => Kept::Whole,
    };
    let (result, key) = (result.clone(), id.to_owned());
    let bytes = crate::cpu::spawn(move || {
        let mut bytes = Vec::with_capacity(compact::size(&result, &key) as usize);
        compact::write(&result, &key, &mut bytes).map(|_| bytes)
    })
    .await;
    Some((bytes.ok()?.ok()?, kept))
}

/// Tells the store that run `token` of job `id` ended: its result, then its final posting. Says
/// whether that is done (or can never be: another run holds the job now), false while the store
/// is away.
async fn deliver(
    peers: &dyn Peers,
    id: &str,
    token: &str,
    result: Option<&(Vec<u8>, Kept)>,
    posting: &Posting,
) -> bool {
    // A whole result first, lease or not: every run of an id makes the same bytes, so a run
    // that took the job over while this one could not reach the store finds it stored instead
    // of running the job again. A partial one is this run's own (another run stops at
    // another count): only while it holds the lease.
    if let Some((bytes, Kept::Whole)) = result
        && !store(peers, id, Kept::Whole, bytes).await
    {
        return false;
    }
    // The lease may be gone: it lapsed while the store was away, or the store restarted empty.
    match peers.renew(id, token).await {
        Ok(true) => {}
        Ok(false) => match peers.acquire(id, token, Take::Over).await {
            Ok(Acquired::Won) => {}
            Ok(Acquired::Held(_)) => return true,
            Err(_) => return false,
        },
        Err(_) => return false,
    }
    if let Some((bytes, Kept::Partial)) = result
        && !store(peers, id, Kept::Partial, bytes).await
    {
        return false;
    }
    match peers.post(id, Some(token), posting).await {
        Ok(true) => {}
        // Another run holds the job now: what it keeps is its own.
        Ok(false) => return true,
        Err(_) => return false,
    }
    let _ = peers.forget(id).await;
    let _ = peers.release(id, token).await;
    true
}

/// Stores a whole result in the store; false while the store is away (or it cannot be encoded).
pub(super) async fn store_result(peers: &dyn Peers, id: &str, result: &Arc<RunResult>) -> bool {
    match encode(id, result).await {
        Some((bytes, kept)) => store(peers, id, kept, &bytes).await,
        None => false,
    }
}

/// Stores a result's compact bytes; false while the store is away. One larger than
/// `MESHFIT_REDIS_MAX_BYTES` is not stored, and only its replica serves it.
async fn store(peers: &dyn Peers, id: &str, kept: Kept, bytes: &[u8]) -> bool {
    match peers.keep_result(id, kept, bytes).await {
        Ok(true) => true,
        Ok(false) => {
            tracing::info!(job = id, bytes = bytes.len(), "result not stored in redis");
            true
        }
        Err(_) => false,
    }
}

/// Ends run `token` of job `id` with its final `posting`: stored and sent, the job off the
/// pending list, the lease given up.
pub(super) async fn close(peers: &dyn Peers, id: &str, token: &str, posting: &Posting) {
    // Only while this run holds the lease: another run's pending entry and keys are its own.
    if let Ok(true) = peers.post(id, Some(token), posting).await {
        let _ = peers.forget(id).await;
    }
    let _ = peers.release(id, token).await;
}

/// The final posting of a run that ended `status`, numbered after `seq`, written by another
/// than the run itself (a takeover that found it ended, a follower that found it lost).
pub(super) fn ended(
    status: Status,
    stats: Option<Summary>,
    failure: Option<Failure>,
    seq: u64,
    token: &str,
) -> Posting {
    Posting {
        status: status.as_str().to_owned(),
        seq: seq + 1,
        progress: None,
        stats,
        failure,
        elapsed_ms: None,
        run: token.to_owned(),
    }
}

/// A snapshot as replicas exchange it.
fn wire(s: &Snapshot, failure: Option<Failure>, token: &str) -> Posting {
    let stats = match &s.outcome {
        Some(Outcome::Succeeded(result)) => Some(result.stats.clone()),
        _ => None,
    };
    Posting {
        status: s.status.as_str().to_owned(),
        seq: s.seq,
        progress: s.progress,
        stats,
        failure,
        elapsed_ms: s.elapsed.map(|d| d.as_secs_f64() * 1e3),
        run: token.to_owned(),
    }
}
