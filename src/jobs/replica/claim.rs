//! Who runs a job among the replicas: the one whose run takes its lease. [`claim`] is the one
//! call a submission makes to decide it.

use super::lease::LeaseGuard;
use super::peers::{Acquired, Asked, Peers, Take};
use std::sync::Arc;
use std::time::Duration;

/// Who runs a job, as the replicas decided it.
pub(in crate::jobs) enum Claim<T> {
    /// This replica's new run holds the lease: run the job here, publishing it. The lease is
    /// given back when the guard is dropped armed (the run never started).
    Run(LeaseGuard),
    /// Another replica's run (this token) holds it: follow that run.
    Follow(String),
    /// No store, or it did not answer: run the job here, unshared.
    Alone,
    /// A run of this replica holds it, one a concurrent identical request is starting: joined
    /// (what the caller's `join` gave).
    Joined(T),
}

/// The lease stayed with a run that has ended, or was asked to, for longer than a lease: the
/// submission is refused, to be made again later.
#[derive(Debug)]
pub(in crate::jobs) struct Busy;

/// How often a claim looks again at a run that holds the job's lease and will not run it for
/// this request: one of this replica being started by a concurrent identical request (to
/// join), or one that has ended, or was asked to, and not yet let go of its lease (for at
/// most a lease, then the claim gives up with [`Busy`]).
const OWN_RUN_WAIT: Duration = Duration::from_millis(25);

/// Decides who runs job `id`: takes its lease for a new run of this replica, or finds the run
/// of another replica to follow, or the store away. A run of this replica holding the lease
/// is joined through `join` (never mirrored); a run that has ended and not yet let go of the
/// lease is waited for.
///
/// # Errors
/// [`Busy`] when a run that has ended keeps the lease for longer than a lease.
pub(in crate::jobs) async fn claim<T>(
    peers: &Arc<dyn Peers>,
    id: &str,
    mut join: impl FnMut() -> Option<T>,
) -> Result<Claim<T>, Busy> {
    // Guarded from before the first try: a client hanging up while the lease is being taken
    // leaves none behind.
    let guard = LeaseGuard::new(peers, id, peers.token());
    // An ended run lets go of its lease within a lease, even if its release was lost.
    let patience = (peers.lease() + Duration::from_secs(1)).as_millis() / OWN_RUN_WAIT.as_millis();
    let mut waits: u128 = 0;
    loop {
        let held = match peers.acquire(id, guard.token(), Take::Fresh).await {
            Ok(Acquired::Won) => return Ok(Claim::Run(guard)),
            Ok(Acquired::Held(holder)) => holder,
            // The store is away, or there is none: run it here, unshared.
            Err(_) => return Ok(Claim::Alone),
        };
        waits += 1;
        if peers.is_mine(&held) {
            // A run of this replica: one a concurrent identical request is starting (join
            // it), or one ending after a cancel (let it end, then run again). Never a mirror
            // of it.
            if let Some(joined) = join() {
                return Ok(Claim::Joined(joined));
            }
        } else if !has_ended(&**peers, id, &held).await {
            return Ok(Claim::Follow(held));
        }
        // A run that has ended, or was asked to, and not yet let go: wait for its lease.
        if waits >= patience {
            return Err(Busy);
        }
        tokio::time::sleep(OWN_RUN_WAIT).await;
    }
}

/// Whether run `token` of job `id` has posted its end (and is about to let go of
/// its lease), or was asked to stop: a new request must not be given its end.
async fn has_ended(peers: &dyn Peers, id: &str, token: &str) -> bool {
    let ended = matches!(peers.posting(id).await, Ok(Some(r)) if r.run == token && r.is_final());
    ended || matches!(peers.asked(id).await, Ok(Asked { cancel: true, .. }))
}

#[cfg(test)]
mod tests {
    //! `claim` over the in-memory store, on tokio's paused clock.

    use super::*;
    use crate::jobs::replica::peers::Alone;
    use crate::jobs::replica::peers::memory::Bus;

    const LEASE: Duration = Duration::from_secs(2);

    fn pair() -> (Arc<dyn Peers>, Arc<dyn Peers>) {
        let bus = Bus::new(LEASE, 1 << 20);
        (bus.replica("a"), bus.replica("b"))
    }

    #[tokio::test(start_paused = true)]
    async fn a_replica_alone_runs_the_job_alone() {
        let alone: Arc<dyn Peers> = Arc::new(Alone);
        assert!(matches!(claim(&alone, "x", || None::<()>).await, Ok(Claim::Alone)));
    }

    #[tokio::test(start_paused = true)]
    async fn the_first_claim_runs_and_another_replicas_claim_follows_that_run() {
        let (a, b) = pair();
        let Ok(Claim::Run(mut run)) = claim(&a, "x", || None::<()>).await else {
            panic!("a does not run it")
        };
        run.disarm();
        let Ok(Claim::Follow(followed)) = claim(&b, "x", || None::<()>).await else {
            panic!("b does not follow")
        };
        assert_eq!(followed, run.token());
    }

    #[tokio::test(start_paused = true)]
    async fn a_claim_on_a_run_of_this_replica_joins_it_or_waits_until_busy() {
        let (a, _) = pair();
        let Ok(Claim::Run(mut run)) = claim(&a, "x", || None::<()>).await else {
            panic!("a does not run it")
        };
        run.disarm();
        assert!(matches!(claim(&a, "x", || Some(7)).await, Ok(Claim::Joined(7))));
        // The run renews its lease, as an ending run does until it lets go.
        let renewing = tokio::spawn({
            let (a, token) = (a.clone(), run.token().to_owned());
            async move {
                loop {
                    let _ = a.renew("x", &token).await;
                    tokio::time::sleep(a.renew_every()).await;
                }
            }
        });
        // Not joinable (it is ending) and never let go: refused after a lease and a second.
        let mut looks = 0;
        let refused = claim(&a, "x", || {
            looks += 1;
            None::<()>
        })
        .await;
        assert!(matches!(refused, Err(Busy)));
        assert_eq!(looks, (LEASE + Duration::from_secs(1)).as_millis() / OWN_RUN_WAIT.as_millis());
        renewing.abort();
    }

    #[tokio::test(start_paused = true)]
    async fn a_run_dropped_before_it_starts_gives_its_lease_back() {
        let (a, b) = pair();
        let Ok(Claim::Run(run)) = claim(&a, "x", || None::<()>).await else { panic!("a does not run it") };
        drop(run);
        for _ in 0..100 {
            if matches!(b.holder("x").await, Ok(None)) {
                break;
            }
            tokio::task::yield_now().await;
        }
        assert!(matches!(claim(&b, "x", || None::<()>).await, Ok(Claim::Run(_))), "the lease was given back");
    }
}
