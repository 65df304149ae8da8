//! Taking over jobs whose replica died: every half lease (at least every second), each
//! replica looks at the pending jobs, and the first to take the lease of one nobody holds
//! runs it again from its kept request. Results are deterministic, so the clients following it get the same bytes the
//! dead replica would have stored.

use super::registry::{Inner, Start, Ticket};
use super::share::Client;
use crate::cluster::Cluster;
use std::sync::{Arc, Weak};
use std::time::Duration;

/// Looks for orphaned jobs until the registry is gone or closed. Also pings Redis, so that
/// `/readyz` and `/metrics` say whether it answers even when no request needs it.
pub(super) async fn sweep(inner: Weak<Inner>) {
    let mut first = true;
    loop {
        if !std::mem::take(&mut first) {
            let every = {
                let Some(inner) = inner.upgrade() else { return };
                let Some(shared) = &inner.shared else { return };
                sweep_every(shared.cluster.settings().lease)
            };
            tokio::time::sleep(every).await;
        }
        let Some(inner) = inner.upgrade() else { return };
        if inner.closed.load(std::sync::atomic::Ordering::SeqCst) {
            return;
        }
        let Some(shared) = &inner.shared else { return };
        let cluster = shared.cluster.clone();
        if cluster.ping().await.is_err() {
            continue;
        }
        let Ok(ids) = cluster.pending().await else { continue };
        for id in ids {
            if inner.runs_here(&id) || !matches!(cluster.is_leased(&id).await, Ok(false)) {
                continue;
            }
            let record = cluster.record(&id).await.ok().flatten();
            if record.as_ref().is_some_and(|r| r.is_final()) {
                let _ = cluster.forget(&id).await;
                continue;
            }
            if matches!(cluster.acquire(&id).await, Ok(true)) {
                take_over(&inner, &cluster, &id, record.map_or(0, |r| r.seq)).await;
            }
        }
    }
}

/// How often pending jobs are looked at: every half lease, and at least every second, so that
/// a job handed back at shutdown is taken over at once whatever the lease.
pub(super) fn sweep_every(lease: Duration) -> Duration {
    (lease / 2).clamp(Duration::from_millis(20), Duration::from_secs(1))
}

/// Runs job `id`, whose lease this replica has just taken, from its kept request.
async fn take_over(inner: &Arc<Inner>, cluster: &Cluster, id: &str, seq: u64) {
    let Some(shared) = &inner.shared else { return };
    let parsed = match cluster.request(id).await {
        Ok(Some(request)) => shared.wire.parse(request).await,
        Ok(None) => Err("its request is no longer kept".to_owned()),
        Err(e) => Err(e.to_string()),
    };
    let (keys, spec) = match parsed {
        Ok((keys, spec)) if keys.id == id => (keys, spec),
        outcome => {
            let why = outcome.err().unwrap_or_else(|| "its request gives another id here".into());
            tracing::warn!(job = id, %why, "cannot take the job over; dropping it");
            let _ = cluster.forget(id).await;
            let _ = cluster.release(id).await;
            return;
        }
    };
    let start = Start { id: keys.id, family: keys.family, seq, leased: true, request: None };
    match inner.start(start, spec, true, &Client::from("replica:takeover".to_owned())) {
        Ok(Ticket::Job(_)) => {
            inner.metrics.takeovers.inc();
            tracing::info!(job = id, "took over a job whose replica stopped renewing its lease");
        }
        // Busy here: another replica, or this one at the next sweep, takes it.
        _ => {
            let _ = cluster.release(id).await;
        }
    }
}
