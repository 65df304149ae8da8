//! The replica running a shared job tells the others about it: keeps its request for a
//! takeover, stores its record as it changes (at most every [`PUBLISH_EVERY`]), renews its
//! lease, and at the end stores the result before the final record, so that a replica that
//! reads the record can fetch the result.

use super::job::{Job, Outcome, Snapshot, Status};
use super::registry::Inner;
use crate::cluster::{self, Request};
use crate::refine::StopReason;
use crate::result::compact;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::time::Instant;

/// Records go out at most this often while a job runs; the final one at once.
const PUBLISH_EVERY: Duration = Duration::from_millis(100);

/// Publishes job `job`, whose lease this replica holds, until it finishes.
pub(super) async fn run(inner: &Arc<Inner>, job: Arc<Job>, request: Option<Request>) {
    let Some(shared) = &inner.shared else { return };
    let cluster = &shared.cluster;
    if let Some(request) = request
        && !matches!(cluster.put_request(&job.id, &request).await, Ok(true))
    {
        tracing::debug!(job = %job.id, "request not kept in redis: no other replica can take this job over");
    }
    let mut rx = job.subscribe();
    let mut renew = tokio::time::interval(cluster.settings().lease / 3);
    renew.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut sent: Option<(u64, Status)> = None;
    let mut last = None::<Instant>;
    loop {
        let snapshot = rx.borrow_and_update().clone();
        if snapshot.outcome.is_some() {
            return finish(inner, &job, &snapshot).await;
        }
        let fresh = sent != Some((snapshot.seq, snapshot.status));
        let due = last.map(|t| t + PUBLISH_EVERY).filter(|_| fresh);
        if fresh && due.is_none_or(|due| Instant::now() >= due) {
            let _ = cluster.put_record(&job.id, &wire(&snapshot, None, cluster.replica())).await;
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
            _ = renew.tick() => {
                if let Ok(false) = cluster.renew(&job.id).await {
                    // Redis was away past the lease, and another replica may run it too:
                    // both make the same bytes, so this run goes on.
                    tracing::warn!(job = %job.id, "lease lost");
                }
                if let Ok(true) = cluster.is_cancelled(&job.id).await {
                    job.cancel();
                }
            }
        }
    }
}

/// Stores job `job`'s record as it is now.
pub(super) async fn announce(inner: &Inner, job: &Job) {
    if let Some(shared) = &inner.shared {
        let record = wire(&job.snapshot(), None, shared.cluster.replica());
        let _ = shared.cluster.put_record(&job.id, &record).await;
    }
}

/// Stores the result and the final record, takes the job off the pending list and gives up
/// the lease; a job handed back at shutdown only gives up its lease, for a takeover.
async fn finish(inner: &Arc<Inner>, job: &Job, snapshot: &Snapshot) {
    let Some(shared) = &inner.shared else { return };
    let cluster = &shared.cluster;
    let problem = match snapshot.outcome.as_ref().expect("finished") {
        Outcome::Cancelled if job.handed_back.load(Ordering::SeqCst) => {
            tracing::info!(job = %job.id, "handed back for another replica to take over");
            let _ = cluster.release(&job.id).await;
            return;
        }
        Outcome::Succeeded(result) => {
            let partial = result.stats.stop() == StopReason::TimeLimit;
            let (result, id) = (result.clone(), job.id.clone());
            let bytes = crate::cpu::spawn(move || {
                let mut bytes = Vec::with_capacity(compact::size(&result, &id) as usize);
                compact::write(&result, &id, &mut bytes).map(|_| bytes)
            })
            .await;
            if let Ok(Ok(bytes)) = bytes
                && !matches!(cluster.put_result(&job.id, partial, &bytes).await, Ok(true))
            {
                tracing::info!(job = %job.id, bytes = bytes.len(), "result not stored in redis");
            }
            None
        }
        Outcome::Failed(e) => Some(shared.wire.problem(e)),
        Outcome::Cancelled => None,
    };
    let _ = cluster.put_record(&job.id, &wire(snapshot, problem, cluster.replica())).await;
    let _ = cluster.forget(&job.id).await;
    let _ = cluster.release(&job.id).await;
}

/// A snapshot as replicas exchange it.
fn wire(s: &Snapshot, problem: Option<serde_json::Value>, replica: &str) -> cluster::Record {
    let stats = match &s.outcome {
        Some(Outcome::Succeeded(result)) => Some(result.stats.clone()),
        _ => None,
    };
    cluster::Record {
        status: s.status.as_str().to_owned(),
        seq: s.seq,
        progress: s.progress,
        stats,
        problem,
        elapsed_ms: s.elapsed.map(|d| d.as_secs_f64() * 1e3),
        replica: replica.to_owned(),
    }
}
