//! Taking over jobs whose replica died: every half lease (at least every second), each
//! replica looks at the pending jobs, and the first to take the lease of one nobody holds
//! runs it again from its kept spec. Results are deterministic, so the clients following
//! it get the same bytes the dead replica would have stored.

use super::follow::{self, Fetched};
use super::lease::Lease;
use super::peers::{Acquired, Kept, Take};
use super::publish;
use crate::jobs::Failure;
use crate::jobs::inner::Inner;
use crate::jobs::job::{Lifetime, Status};
use crate::jobs::share::Client;
use crate::jobs::start::Start;
use crate::spec::{JobKeys, JobSpec, Limits, canonical, job_keys};
use std::sync::{Arc, Weak};

/// Looks for orphaned jobs until the registry is gone or closed. Also pings the store first, so
/// that `/readyz` and `/metrics` say whether it answers even when no request needs it.
pub(in crate::jobs) async fn sweep(inner: Weak<Inner>, limits: Limits) {
    loop {
        // Held only while sweeping: the registry may go between sweeps.
        let every = {
            let Some(inner) = inner.upgrade() else { return };
            if inner.admission.is_closed() {
                return;
            }
            sweep_once(&inner, &limits).await;
            inner.peers.sweep_every()
        };
        tokio::time::sleep(every).await;
    }
}

/// One look at the pending jobs, after a ping.
async fn sweep_once(inner: &Arc<Inner>, limits: &Limits) {
    let peers = &*inner.peers;
    if peers.ping().await.is_err() {
        return;
    }
    let Ok(ids) = peers.pending().await else { return };
    for id in ids {
        if !inner.admission.has_room() {
            // A takeover would be refused: leave the jobs to replicas with room.
            break;
        }
        if inner.table.runs_here(&id) || !matches!(peers.holder(&id).await, Ok(None)) {
            continue;
        }
        let token = peers.token();
        if let Ok(Acquired::Won) = peers.acquire(&id, &token, Take::Over).await
            && take_over(inner, limits, &id, token).await == Taken::Refused
        {
            // Full here: the other jobs would be fetched, decoded and refused too. Another
            // replica, or this one at a later sweep, takes them.
            break;
        }
    }
}

/// What a takeover came to.
#[derive(Debug, PartialEq, Eq)]
enum Taken {
    /// Run here, ended, or left for a later sweep.
    Done,
    /// This replica has no room for it now.
    Refused,
}

/// Ends or runs again job `id`, whose lease run `token` has just taken: ends it if it finished
/// after all (its replica died between storing the result and the final posting) or cannot be
/// run here, else starts it from its kept spec, held to this replica's `limits`.
async fn take_over(inner: &Arc<Inner>, limits: &Limits, id: &str, token: String) -> Taken {
    let peers = &*inner.peers;
    let Ok(posting) = peers.posting(id).await else {
        let _ = peers.release(id, &token).await;
        return Taken::Done;
    };
    let seq = posting.as_ref().map_or(0, |r| r.seq);
    if posting.as_ref().is_some_and(|r| r.is_final()) {
        let _ = peers.forget(id).await;
        let _ = peers.release(id, &token).await;
        return Taken::Done;
    }
    let here = inner.cache.get_memory(id).is_some();
    match follow::fetch(inner, id, Kept::Whole).await {
        Fetched::Found(result) => {
            // In this replica's memory it may be nowhere else: this replica ran the job and
            // has not yet told the store (an outage outlasted the lease). Stored first, so that
            // the final posting never sends followers to a result the store does not have.
            if here && !publish::store_result(peers, id, &result).await {
                let _ = peers.release(id, &token).await;
                return Taken::Done;
            }
            let posting = publish::ended(Status::Succeeded, Some(result.stats.clone()), None, seq, &token);
            publish::close(peers, id, &token, &posting).await;
            return Taken::Done;
        }
        Fetched::Missing => {}
        // The store went away meanwhile: the next sweep, here or elsewhere, tries again.
        Fetched::Unreachable => {
            let _ = peers.release(id, &token).await;
            return Taken::Done;
        }
    }
    let decoded = match peers.kept_spec(id).await {
        Ok(Some(bytes)) => decode(bytes, *limits).await,
        Ok(None) => Err("its spec is no longer kept".to_owned()),
        Err(_) => {
            let _ = peers.release(id, &token).await;
            return Taken::Done;
        }
    };
    let (keys, spec) = match decoded {
        Ok((keys, spec)) if keys.id == id => (keys, spec),
        outcome => {
            // Replicas with other limits, say: tell the followers rather than leave them waiting.
            let why = outcome.err().unwrap_or_else(|| "its spec gives another id here".into());
            tracing::warn!(job = id, %why, "cannot take the job over");
            let failure = Failure::internal(format!("could not be taken over: {why}"));
            publish::close(
                peers,
                id,
                &token,
                &publish::ended(Status::Failed, None, Some(failure), seq, &token),
            )
            .await;
            return Taken::Done;
        }
    };
    let lease = Lease { token: token.clone(), announced: None };
    let start = Start { id: keys.id, family: keys.family, seq, lease: Some(lease), keep: false };
    match inner.start(start, spec, Lifetime::Detached, &Client::from("replica:takeover".to_owned())) {
        Ok((_, true)) => {
            inner.metrics.takeovers.inc();
            tracing::info!(job = id, "took over a job whose replica stopped renewing its lease");
            Taken::Done
        }
        // Already run here.
        Ok((_, false)) => {
            let _ = peers.release(id, &token).await;
            Taken::Done
        }
        // Busy here: another replica, or this one at a later sweep, takes it.
        Err(_) => {
            let _ = peers.release(id, &token).await;
            Taken::Refused
        }
    }
}

/// Kept specs up to this size are read on the async worker: a trip to the blocking pool
/// would cost more.
const INLINE_SPEC_BYTES: usize = 16 << 10;

/// A kept spec read back, with its keys; a large one (a grid's) on the blocking pool.
async fn decode(bytes: Vec<u8>, limits: Limits) -> Result<(JobKeys, JobSpec), String> {
    let inline = bytes.len() <= INLINE_SPEC_BYTES;
    let decode = move || {
        let spec = canonical::decode(&bytes, &limits).map_err(|e| e.to_string())?;
        Ok((job_keys(&spec), spec))
    };
    if inline {
        return decode();
    }
    crate::cpu::spawn(decode).await.unwrap_or_else(|e| Err(format!("decoding panicked: {e}")))
}
