//! The replica protocol in memory: two or three registries over one [`Bus`], on tokio's
//! paused clock. Each test decides when the engine runs by holding a replica's only worker
//! ([`Jobs::hold_worker`]): a job stays queued, with its lease, posting and kept request,
//! until the test lets go. No test waits on a job being "long enough".

use super::Peers;
use super::memory::{Bus, Replica};
use crate::api::JobRequest;
use crate::jobs::dispatch::Worker;
use crate::jobs::{Cache, Client, JobError, Jobs, Lifetime, Outcome, Pool, Ticket, Waiter};
use crate::metrics::Metrics;
use crate::result::{RunResult, compact};
use crate::spec::{JobKeys, JobSpec, Limits, job_keys};
use std::num::NonZeroUsize;
use std::sync::Arc;
use std::time::Duration;
use tokio::time::timeout;

/// A lease short enough that a replica cut off loses its jobs within a few seconds.
const LEASE: Duration = Duration::from_secs(2);

/// A lease no test outlives: only a hand-back, never a lapse, lets another replica in.
const DAY: Duration = Duration::from_secs(86_400);

const BODY: &str = r#"{"function": "x*y + sin(3*x)", "max_vertices": 300}"#;
const OTHER: &str = r#"{"function": "x - y*y", "max_vertices": 200}"#;

fn limits() -> Limits {
    Limits {
        max_vertices: 100_000,
        max_grid_points: 1000,
        max_expression_len: 100,
        job_time_limit: Duration::from_secs(600),
    }
}

fn parsed(body: &[u8]) -> Result<(JobKeys, JobSpec), String> {
    let request: JobRequest = serde_json::from_slice(body).map_err(|e| e.to_string())?;
    let spec = JobSpec::from_request(request, &limits()).map_err(|e| e.to_string())?;
    Ok((job_keys(&spec), spec))
}

fn id_of(body: &str) -> String {
    parsed(body.as_bytes()).unwrap().0.id
}

/// A replica: its registry (one worker) and its handle on the bus.
struct Node {
    jobs: Jobs,
    peers: Arc<Replica>,
}

fn node(bus: &Bus, name: &str) -> Node {
    let peers = bus.replica(name);
    let cache = Cache::new(64 << 20, None, 0).unwrap();
    let pool = Pool {
        workers: NonZeroUsize::MIN,
        queue: 4,
        client_share: 1.0,
        memory_bytes: 8 << 30,
        job_retention: std::time::Duration::from_secs(3600),
    };
    let jobs = Jobs::new(&pool, cache, Arc::new(Metrics::default())).shared(peers.clone(), limits());
    Node { jobs, peers }
}

impl Node {
    async fn submit(&self, body: &str, lifetime: Lifetime) -> Ticket {
        let (keys, spec) = parsed(body.as_bytes()).unwrap();
        let client = Client::from(format!("test:{lifetime:?}"));
        let submitted = self.jobs.submit(keys, spec, lifetime, &client).await;
        submitted.unwrap_or_else(|e| panic!("refused: {e}"))
    }

    async fn wait_on(&self, body: &str, lifetime: Lifetime) -> Waiter {
        match self.submit(body, lifetime).await {
            Ticket::Job(waiter) => waiter,
            _ => panic!("expected a job"),
        }
    }

    fn engine_runs(&self) -> u64 {
        self.jobs.metrics().engine_runs.get()
    }
}

/// Two replicas on a bus whose leases last `lease` and that keeps up to `max_bytes`.
fn pair(lease: Duration, max_bytes: usize) -> (Bus, Node, Node) {
    let bus = Bus::new(lease, max_bytes);
    let (a, b) = (node(&bus, "a"), node(&bus, "b"));
    (bus, a, b)
}

/// [`BODY`] submitted on `a` for `lifetime` and then on `b`, which follows `a`'s run; the
/// job waits on `a` until the test drops the worker held here.
async fn followed(a: &Node, b: &Node, lifetime: Lifetime) -> (Worker, Waiter, Waiter) {
    let held = a.jobs.hold_worker().await;
    let on_a = a.wait_on(BODY, lifetime).await;
    let on_b = b.wait_on(BODY, Lifetime::WhileWaited).await;
    assert!(!on_a.job().follows && on_b.job().follows, "b follows a's run");
    (held, on_a, on_b)
}

async fn succeeded(waiter: &Waiter) -> Arc<RunResult> {
    match waiter.job().outcome().await {
        Outcome::Succeeded(result) => result,
        other => panic!("expected a result, got {other:?}"),
    }
}

fn compact(result: &RunResult, id: &str) -> Vec<u8> {
    let mut bytes = Vec::new();
    compact::write(result, id, &mut bytes).unwrap();
    bytes
}

/// Waits (on the paused clock) until `check` holds.
async fn until(mut check: impl FnMut() -> bool) {
    for _ in 0..10_000 {
        if check() {
            return;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    panic!("waited 100 s in vain");
}

#[tokio::test(start_paused = true)]
async fn a_job_run_on_one_replica_is_followed_on_another_and_runs_once() {
    let (_, a, b) = pair(LEASE, 1 << 20);
    let (held, on_a, on_b) = followed(&a, &b, Lifetime::WhileWaited).await;
    drop(held);
    let (got_a, got_b) = (succeeded(&on_a).await, succeeded(&on_b).await);
    let id = id_of(BODY);
    assert_eq!(compact(&got_a, &id), compact(&got_b, &id), "the same bytes on both replicas");
    assert_eq!((a.engine_runs(), b.engine_runs()), (1, 0));
    assert_eq!(b.jobs.metrics().jobs_followed.get(), 1);
    assert_eq!(b.jobs.metrics().shared_hits.get(), 1, "b read the result from the store");
}

#[tokio::test(start_paused = true)]
async fn identical_requests_arriving_together_on_two_replicas_run_once() {
    let (_, a, b) = pair(LEASE, 1 << 20);
    let (on_a, on_b) =
        tokio::join!(a.wait_on(BODY, Lifetime::WhileWaited), b.wait_on(BODY, Lifetime::WhileWaited));
    assert_ne!(on_a.job().follows, on_b.job().follows, "one runs, the other follows");
    let id = id_of(BODY);
    assert_eq!(compact(&*succeeded(&on_a).await, &id), compact(&*succeeded(&on_b).await, &id));
    assert_eq!(a.engine_runs() + b.engine_runs(), 1);
}

#[tokio::test(start_paused = true)]
async fn a_job_whose_replica_is_cut_off_is_taken_over_from_its_kept_request() {
    let (bus, a, b) = pair(LEASE, 1 << 20);
    let (_held, on_a, on_b) = followed(&a, &b, Lifetime::Detached).await;
    let id = id_of(BODY);
    until(|| bus.is_listed(&id)).await;
    // As far as the others can tell, a died: it renews nothing from now on.
    a.peers.cut(true);
    let early = timeout(LEASE - Duration::from_millis(1), on_b.job().outcome()).await;
    assert!(early.is_err() && b.jobs.metrics().takeovers.get() == 0, "not before a's lease lapsed");
    succeeded(&on_b).await;
    assert_eq!(b.jobs.metrics().takeovers.get(), 1);
    assert_eq!((a.engine_runs(), b.engine_runs()), (0, 1));
    let last = bus.posting_of(&id).unwrap();
    assert_eq!(last.status, "succeeded");
    assert!(b.peers.is_mine(&last.run), "b's run posted the end");
    assert!(!bus.is_listed(&id), "a finished job is no longer pending");
    assert!(!on_a.job().is_finished(), "a never ran it");
}

#[tokio::test(start_paused = true)]
async fn a_job_handed_back_at_shutdown_is_taken_over_at_once() {
    let (bus, a, b) = pair(DAY, 1 << 20);
    let (_held, on_a, on_b) = followed(&a, &b, Lifetime::Detached).await;
    let id = id_of(BODY);
    until(|| bus.is_listed(&id)).await;
    a.jobs.close();
    a.jobs.cancel_all();
    // Within a sweep (a second) to take it over and a look of b's mirror (another) to see
    // it end, not a lease (a day). (The mirror looks on its own clock: b's own run now holds
    // the job's place in b's table, and postings wake only the mirror found there.)
    let handed = timeout(Duration::from_secs(5), async {
        assert_eq!(on_a.job().outcome().await, Outcome::Failed(JobError::HandedBack));
        succeeded(&on_b).await;
    });
    handed.await.expect("taken over within seconds, not a lease");
    assert_eq!(b.jobs.metrics().takeovers.get(), 1);
    assert_eq!((a.engine_runs(), b.engine_runs()), (0, 1));
    assert!(!a.jobs.is_busy(), "a has let go of everything it held");
}

#[tokio::test(start_paused = true)]
async fn a_follower_ends_a_job_that_no_replica_runs_or_can_take_over() {
    // Requests of more than 8 bytes are not kept: nobody can take the job over.
    let (bus, a, b) = pair(LEASE, 8);
    let (_held, _on_a, on_b) = followed(&a, &b, Lifetime::Detached).await;
    a.peers.cut(true);
    let Outcome::Failed(JobError::Internal(why)) = on_b.job().outcome().await else { panic!("not failed") };
    assert!(why.contains("run by no replica"), "{why}");
    // Ended for every replica, saying why.
    let last = bus.posting_of(&id_of(BODY)).unwrap();
    assert_eq!(last.status, "failed");
    assert_eq!(last.failure, Some(JobError::Internal(why).failure()));
    assert_eq!(b.engine_runs(), 0);
}

#[tokio::test(start_paused = true)]
async fn a_failure_on_the_input_reads_the_same_on_the_replica_that_follows() {
    const POLE: &str = r#"{"function": "1/(x-0.5)", "max_vertices": 100}"#;
    let (bus, a, b) = pair(LEASE, 1 << 20);
    let held = a.jobs.hold_worker().await;
    let on_a = a.wait_on(POLE, Lifetime::WhileWaited).await;
    let on_b = b.wait_on(POLE, Lifetime::WhileWaited).await;
    assert!(on_b.job().follows);
    drop(held);
    let Outcome::Failed(here @ JobError::Refine(_)) = on_a.job().outcome().await else {
        panic!("not failed")
    };
    let Outcome::Failed(there @ JobError::Relayed(_)) = on_b.job().outcome().await else {
        panic!("not relayed")
    };
    // The store holds the engine's failure, not a rendering of it: field, point and message
    // reach b as a's clients see them.
    assert_eq!(there.failure(), here.failure());
    assert_eq!(bus.posting_of(&id_of(POLE)).unwrap().failure, Some(here.failure()));
    assert_eq!(b.engine_runs(), 0);
}

#[tokio::test(start_paused = true)]
async fn cancelling_on_the_follower_stops_the_run_where_it_runs() {
    let (bus, a, b) = pair(LEASE, 1 << 20);
    let (_held, on_a, on_b) = followed(&a, &b, Lifetime::Detached).await;
    b.jobs.cancel(on_b.job()).await.unwrap();
    assert_eq!(on_a.job().outcome().await, Outcome::Cancelled, "stopped on a");
    assert_eq!(on_b.job().outcome().await, Outcome::Cancelled, "and b hears of it");
    assert_eq!(bus.posting_of(&id_of(BODY)).unwrap().status, "cancelled");
    assert_eq!((a.engine_runs(), b.engine_runs()), (0, 0));
}

#[tokio::test(start_paused = true)]
async fn a_cancel_whose_message_is_lost_is_read_from_its_mark_at_the_next_renewal() {
    let (bus, a, b) = pair(LEASE, 1 << 20);
    let (_held, on_a, on_b) = followed(&a, &b, Lifetime::Detached).await;
    bus.lose_controls(true);
    b.jobs.cancel(on_b.job()).await.unwrap();
    // Not at once (the message was lost): at a's next renewal, within a third of a lease.
    let at_once = timeout(Duration::from_millis(1), on_a.job().outcome()).await;
    assert!(at_once.is_err(), "the lost message cancelled it");
    let at_renewal = timeout(LEASE / 3, on_a.job().outcome()).await;
    assert_eq!(at_renewal.expect("cancelled at the next renewal"), Outcome::Cancelled);
    assert_eq!(on_b.job().outcome().await, Outcome::Cancelled);
}

#[tokio::test(start_paused = true)]
async fn a_follower_keeps_the_run_going_when_its_own_client_leaves() {
    let (_, a, b) = pair(LEASE, 1 << 20);
    let (held, on_a, on_b) = followed(&a, &b, Lifetime::WhileWaited).await;
    let job = on_a.job().clone();
    until(|| job.is_detached()).await;
    // a's only client hangs up: without b's request the job would be cancelled here.
    drop(on_a);
    drop(held);
    assert!(matches!(job.outcome().await, Outcome::Succeeded(_)));
    succeeded(&on_b).await;
    assert_eq!(a.engine_runs(), 1);
}

#[tokio::test(start_paused = true)]
async fn while_the_store_is_away_replicas_run_alone_and_share_again_when_it_returns() {
    let (bus, a, b) = pair(LEASE, 1 << 20);
    bus.set_up(false);
    let (on_a, on_b) =
        (a.wait_on(BODY, Lifetime::WhileWaited).await, b.wait_on(BODY, Lifetime::WhileWaited).await);
    assert!(!on_a.job().follows && !on_b.job().follows, "each runs its own");
    succeeded(&on_a).await;
    succeeded(&on_b).await;
    assert_eq!((a.engine_runs(), b.engine_runs()), (1, 1));
    assert_eq!(a.jobs.redis(), Some(false), "health says the store is away");
    bus.set_up(true);
    // The sweep's ping finds it again.
    until(|| a.jobs.redis() == Some(true) && b.jobs.redis() == Some(true)).await;
    let _held = a.jobs.hold_worker().await;
    let _on_a = a.wait_on(OTHER, Lifetime::WhileWaited).await;
    assert!(b.wait_on(OTHER, Lifetime::WhileWaited).await.job().follows, "shared again");
}

#[tokio::test(start_paused = true)]
async fn a_run_that_ended_while_cut_off_tells_the_others_when_it_is_back() {
    let (bus, a, b) = pair(DAY, 1 << 20);
    let (held, on_a, on_b) = followed(&a, &b, Lifetime::WhileWaited).await;
    let id = id_of(BODY);
    until(|| bus.is_listed(&id)).await;
    a.peers.cut(true);
    drop(held);
    let result = succeeded(&on_a).await;
    tokio::time::sleep(Duration::from_secs(5)).await;
    assert!(!on_b.job().is_finished() && !bus.has_result(&id), "nothing reached the store");
    a.peers.cut(false);
    assert_eq!(compact(&*succeeded(&on_b).await, &id), compact(&result, &id));
    assert_eq!((a.engine_runs(), b.engine_runs()), (1, 0));
    assert!(!bus.is_listed(&id));
}

#[tokio::test(start_paused = true)]
async fn a_result_stored_by_one_replica_answers_lookups_and_requests_on_another() {
    let (bus, a, b) = pair(LEASE, 1 << 20);
    let on_a = a.wait_on(BODY, Lifetime::WhileWaited).await;
    succeeded(&on_a).await;
    let id = id_of(BODY);
    until(|| bus.has_result(&id) && bus.posting_of(&id).is_some_and(|p| p.is_final())).await;
    assert!(matches!(b.jobs.find(&id).await, Some(crate::jobs::Found::Cached(_))));
    assert!(matches!(b.submit(BODY, Lifetime::WhileWaited).await, Ticket::Cached(_)));
    assert_eq!(b.engine_runs(), 0);
    assert_eq!(b.jobs.metrics().shared_hits.get(), 1, "read from the store once, then from memory");
}
