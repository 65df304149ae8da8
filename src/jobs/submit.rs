//! A submission, step by step: a cached result answers at once; a smaller request of a cached
//! run's family is replayed from its trace; an identical job live here is joined; otherwise
//! the replicas decide who runs it ([`claim`]): this replica with a lease (unless the result
//! was stored elsewhere meanwhile), another replica, which this one then follows, or this
//! replica alone, when there is no store or it is away.

use super::admission::SubmitError;
use super::inner::Inner;
use super::job::{JobError, Lifetime, Status};
use super::replica::claim::{Claim, claim};
use super::replica::follow;
use super::replica::lease::{Lease, LeaseGuard};
use super::replica::peers::Kept;
use super::share::Client;
use super::start::Start;
use super::table::Joined;
use super::ticket::Ticket;
use crate::refine::trace::replay;
use crate::result::RunResult;
use crate::spec::{JobKeys, JobSpec};
use std::sync::Arc;

/// Answers from the cache, joins an identical job, follows it on another replica, or starts a
/// new one charged to `client`, to run for `lifetime`, keeping its spec in the store for a
/// takeover when replicas share.
pub(super) async fn submit(
    inner: &Arc<Inner>,
    keys: JobKeys,
    spec: JobSpec,
    lifetime: Lifetime,
    client: &Client,
) -> Result<Ticket, SubmitError> {
    let JobKeys { id, family } = keys;
    if let Some(ticket) = cache_hit(inner, &id, &family).await {
        return Ok(ticket);
    }
    if let Some(ticket) = prefix_replay(inner, &id, &family, &spec).await {
        return Ok(ticket);
    }
    if let Some(ticket) = join(inner, &id, lifetime) {
        return Ok(ticket);
    }
    match claim(&inner.peers, &id, || join(inner, &id, lifetime)).await {
        Ok(Claim::Run(lease)) => {
            let start = ToRun { id, family, spec, lifetime };
            run_leased(inner, lease, start, client).await
        }
        Ok(Claim::Follow(run)) => {
            inner.metrics.cache_misses.inc();
            Ok(Ticket::Job(follow::follow(inner, id, family, Some(run))))
        }
        Ok(Claim::Alone) => {
            let start = Start { id, family, seq: 0, lease: None, keep: false };
            inner.start(start, spec, lifetime, client).map(|(ticket, _)| ticket)
        }
        Ok(Claim::Joined(ticket)) => Ok(ticket),
        Err(_) => Err(inner.admission.queue_full()),
    }
}

/// What a leased run starts with.
struct ToRun {
    id: String,
    family: String,
    spec: JobSpec,
    lifetime: Lifetime,
}

/// The result, cached here or in the store.
async fn cache_hit(inner: &Arc<Inner>, id: &str, family: &str) -> Option<Ticket> {
    let finished = cached(inner, id).await?;
    inner.metrics.cache_hits.inc();
    // A run read back from disk after a restart answers its family from now on.
    inner.families.note(family, id, &finished);
    Some(Ticket::Cached(finished))
}

/// The result replayed from the furthest cached run of its family.
async fn prefix_replay(inner: &Arc<Inner>, id: &str, family: &str, spec: &JobSpec) -> Option<Ticket> {
    let result = prefix(inner, id, family, spec).await?;
    inner.metrics.prefix_hits.inc();
    Some(Ticket::Prefix(result))
}

/// Answers from the table: joins a live job, repeats a failure on the input, or finds a
/// result cached since the caller's lookup.
fn join(inner: &Arc<Inner>, id: &str, lifetime: Lifetime) -> Option<Ticket> {
    match inner.table.join(id, lifetime)? {
        Joined::Job(waiter) => {
            inner.metrics.cache_misses.inc();
            Some(Ticket::Job(waiter))
        }
        Joined::Done(record) => match &record.error {
            // A failure on the input is deterministic: it is the answer again.
            Some(e @ JobError::Refine(_)) => {
                inner.metrics.cache_misses.inc();
                Some(Ticket::Failed(e.clone()))
            }
            // It may have been cached between the lookup and the table's answer.
            _ if record.status == Status::Succeeded => {
                let finished = inner.cache.get_memory(id)?;
                inner.metrics.cache_hits.inc();
                Some(Ticket::Cached(finished))
            }
            // Cancelled, an internal error, or a mesh evicted from the cache: run again.
            _ => None,
        },
    }
}

/// Runs the job here under the lease `guard` holds, unless another replica stored its result
/// between the lookup and the lease; the lease is given back unless a run starts with it.
async fn run_leased(
    inner: &Arc<Inner>,
    mut guard: LeaseGuard,
    start: ToRun,
    client: &Client,
) -> Result<Ticket, SubmitError> {
    let ToRun { id, family, spec, lifetime } = start;
    if let Some(ticket) = stored_elsewhere(inner, &id).await {
        return Ok(ticket);
    }
    let (announced, first_posting) = tokio::sync::oneshot::channel();
    let lease = Lease { token: guard.token().to_owned(), announced: Some(announced) };
    let start = Start { id, family, seq: 0, lease: Some(lease), keep: true };
    let (ticket, started) = inner.start(start, spec, lifetime, client)?;
    if started {
        guard.disarm();
        // Stored before the client hears of the job, so that any replica finds it at once.
        let _ = first_posting.await;
    }
    Ok(ticket)
}

/// The result, if it finished on another replica between the lookup and the lease.
async fn stored_elsewhere(inner: &Arc<Inner>, id: &str) -> Option<Ticket> {
    let result = follow::fetch(inner, id, Kept::Whole).await.found()?;
    inner.metrics.cache_hits.inc();
    Some(Ticket::Cached(result))
}

/// The result of `spec` replayed from the furthest cached run of its family, stored under
/// `id`; `None` when there is no such run or the request goes past it.
async fn prefix(inner: &Arc<Inner>, id: &str, family: &str, spec: &JobSpec) -> Option<Arc<RunResult>> {
    let spec = spec.mesh()?;
    let run = inner.families.furthest(family)?;
    let source = cached(inner, &run).await?;
    let trace = source.trace.clone()?;
    let (max_vertices, tolerance) = (spec.params.max_vertices(), spec.params.tolerance());
    if !trace.covers(source.vertices.len(), max_vertices, tolerance) {
        return None;
    }
    let (cache, id, spec) = (inner.cache.clone(), id.to_owned(), spec.clone());
    crate::cpu::spawn(move || {
        let mut replayed = replay(&trace, &source.vertices, max_vertices, tolerance)?;
        spec.measure(&mut replayed);
        let result = Arc::new(RunResult::from(replayed));
        cache.insert(&id, result.clone());
        Some(result)
    })
    .await
    .ok()
    .flatten()
}

/// The cached mesh with this id, if any: in memory, on disk, or, when replicas share, in the
/// store.
pub(super) async fn cached(inner: &Arc<Inner>, id: &str) -> Option<Arc<RunResult>> {
    let cache = &inner.cache;
    if let Some(f) = cache.get_memory(id) {
        return Some(f);
    }
    if cache.has_disk() {
        let (cache, id) = (cache.clone(), id.to_owned());
        let found = tokio::task::spawn_blocking(move || cache.get(&id).map(|(f, _)| f)).await;
        if let Ok(Some(found)) = found {
            return Some(found);
        }
    }
    follow::fetch(inner, id, Kept::Whole).await.found()
}
