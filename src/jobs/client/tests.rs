//! Client jobs over a store shared in memory: one job carried on by several replicas, one
//! that outlives its replica, conflicts told on two replicas, and jobs made `from` others.

use super::*;
use crate::jobs::peers::Alone;
use crate::jobs::replica::peers::memory::Bus;
use crate::result::RunResult;
use serde_json::json;

fn f(x: f64, y: f64) -> f64 {
    (-50.0 * ((x - 0.3).powi(2) + (y - 0.6).powi(2))).exp() + 0.2 * x * y
}

/// Client jobs of a replica on `bus`, or of a replica alone.
fn replica(bus: Option<&Bus>, name: &str) -> ClientJobs {
    let peers: Arc<dyn Peers> = match bus {
        Some(bus) => bus.replica(name),
        None => Arc::new(Alone),
    };
    ClientJobs::new(peers, Limits::NONE)
}

fn request(vertices: u64) -> serde_json::Value {
    json!({"source": "client", "max_vertices": vertices, "batch": 8})
}

/// Makes a job of `request` on `jobs`, with `seeds`.
async fn make(jobs: &ClientJobs, request: serde_json::Value, seeds: Values) -> Arc<ClientJob> {
    let now = Instant::now();
    let spec =
        ClientSpec::from_request(serde_json::from_value(request.clone()).unwrap(), &Limits::NONE).unwrap();
    jobs.create(request, spec, seeds, now).await.unwrap()
}

/// Plays the caller of job `id` until it ends, the `k`th batch on `replicas[k % len]`: the
/// result, and how many points were evaluated.
async fn play(replicas: &[&ClientJobs], id: &str) -> (Arc<RunResult>, u64) {
    // One instant for every call: the job's clock (leases, idleness) never decides here.
    let now = Instant::now();
    let mut evaluated = 0;
    for turn in 0.. {
        let jobs = replicas[turn % replicas.len()];
        let job = jobs.get(id).await.unwrap().expect("every replica finds the job");
        match job.ask(now) {
            Asked::Batch { points, .. } => {
                let told: Vec<_> = points.iter().map(|&(id, p)| (id, Some(f(p.x, p.y)))).collect();
                evaluated += told.len() as u64;
                jobs.tell(&job, &told, now).await.unwrap();
            }
            Asked::Wait { .. } => {
                let changed = job.changed();
                let _ = tokio::time::timeout(Duration::from_millis(20), changed).await;
            }
            Asked::Finished => {
                let result = job.status(now).result.expect("the job succeeded");
                return (result, evaluated);
            }
        }
    }
    unreachable!()
}

fn bits(result: &RunResult) -> (Vec<[u64; 3]>, Vec<[u32; 3]>) {
    let vertices = result.vertices.iter().map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]).collect();
    (vertices, result.triangles.clone())
}

#[tokio::test]
async fn replicas_take_turns_at_one_job_and_make_the_mesh_one_replica_makes() {
    // One instant for every call: the job's clock (leases, idleness) never decides here.
    let now = Instant::now();
    let alone = replica(None, "alone");
    let job = make(&alone, request(120), Values::new()).await;
    let (expected, _) = play(&[&alone], &job.id).await;

    let bus = Bus::new(Duration::from_secs(1), 1 << 20);
    let (a, b, c) = (replica(Some(&bus), "a"), replica(Some(&bus), "b"), replica(Some(&bus), "c"));
    let job = make(&a, request(120), Values::new()).await;
    let (shared, _) = play(&[&a, &b, &c], &job.id).await;
    assert_eq!(bits(&shared), bits(&expected), "the same values make the same mesh");
    assert_eq!(shared.vertices.len(), 120);
    // Every replica holds the finished job, with the same counts.
    let counts: Vec<_> =
        [&a, &b, &c].iter().map(|jobs| jobs.local(&job.id).expect("held").status(now).evaluations).collect();
    assert!(counts.windows(2).all(|w| w[0] == w[1]), "{counts:?}");
}

#[tokio::test]
async fn a_job_outlives_the_replica_that_made_it() {
    // One instant for every call: the job's clock (leases, idleness) never decides here.
    let now = Instant::now();
    let bus = Bus::new(Duration::from_secs(1), 1 << 20);
    let a = replica(Some(&bus), "a");
    let job = make(&a, request(60), Values::new()).await;
    let id = job.id.clone();
    // A tells the corners and the first batch after them, and dies.
    for _ in 0..2 {
        let job = loop {
            let job = a.get(&id).await.unwrap().unwrap();
            if matches!(job.current(now), (_, Some(_))) {
                break job;
            }
            tokio::time::sleep(Duration::from_millis(5)).await;
        };
        let Asked::Batch { points, .. } = job.ask(now) else { panic!("a batch is out") };
        let told: Vec<_> = points.iter().map(|&(id, p)| (id, Some(f(p.x, p.y)))).collect();
        a.tell(&job, &told, now).await.unwrap();
    }
    let told_on_a = job.status(now).evaluations.told;
    drop((a, job));

    let b = replica(Some(&bus), "b");
    let rebuilt = b.get(&id).await.unwrap().expect("rebuilt from the log");
    assert_eq!(rebuilt.status(now).evaluations.told, told_on_a, "nothing told is lost");
    let (result, evaluated) = play(&[&b], &id).await;
    assert_eq!(result.vertices.len(), 60);
    assert_eq!(evaluated + told_on_a, rebuilt.status(now).evaluations.told, "B asked for no told point");

    // A replica alone has no log to rebuild from, and an unknown id is no job.
    assert!(replica(None, "alone").get(&id).await.unwrap().is_none());
    assert!(b.get(&"0".repeat(64)).await.unwrap().is_none());
}

#[tokio::test]
async fn two_replicas_told_different_values_of_a_point_keep_the_first() {
    // One instant for every call: the job's clock (leases, idleness) never decides here.
    let now = Instant::now();
    let bus = Bus::new(Duration::from_secs(1), 1 << 20);
    let (a, b) = (replica(Some(&bus), "a"), replica(Some(&bus), "b"));
    let job_a = make(&a, request(40), Values::new()).await;
    let job_b = b.get(&job_a.id).await.unwrap().unwrap();
    assert_eq!(a.tell(&job_a, &[(0, Some(1.0))], now).await, Ok(1));
    // B has not read A's entry: its tell meets it in the log and is checked against it.
    let conflict = b.tell(&job_b, &[(1, Some(2.0)), (0, Some(3.0))], now).await;
    assert_eq!(
        conflict,
        Err(ClientError::Tell(TellError::Conflict { index: 1, id: 0, was: Some(1.0), told: Some(3.0) }))
    );
    assert_eq!(job_b.status(now).evaluations.told, 1, "all or none: point 1 was not told");
    assert_eq!(b.tell(&job_b, &[(0, Some(1.0))], now).await, Ok(0), "a repeat is a no-op");
    // A cancellation on B ends the job on A.
    b.cancel(&job_b, now).await.unwrap();
    let job_a = a.get(&job_a.id).await.unwrap().unwrap();
    assert_eq!(job_a.status(now).status, "cancelled");
}

#[tokio::test]
async fn a_store_away_refuses_tells_and_loses_nothing() {
    // One instant for every call: the job's clock (leases, idleness) never decides here.
    let now = Instant::now();
    let bus = Bus::new(Duration::from_secs(1), 1 << 20);
    let (a, b) = (replica(Some(&bus), "a"), replica(Some(&bus), "b"));
    let job = make(&a, request(40), Values::new()).await;
    bus.set_up(false);
    assert_eq!(a.tell(&job, &[(0, Some(1.0))], now).await, Err(ClientError::Unreachable));
    assert_eq!(job.status(now).evaluations.told, 0, "a value the store did not take is not told");
    bus.set_up(true);
    // The next operation finds the store again once a ping has (as the registry's sweep does).
    a.peers.ping().await.unwrap();
    assert_eq!(a.tell(&job, &[(0, Some(1.0))], now).await, Ok(1));
    let on_b = b.get(&job.id).await.unwrap().unwrap();
    assert_eq!(on_b.status(now).evaluations.told, 1);
}

#[tokio::test]
async fn a_job_from_another_asks_only_for_what_that_one_was_not_told() {
    for bus in [None, Some(Bus::new(Duration::from_secs(1), 1 << 20))] {
        let jobs = replica(bus.as_ref(), "a");
        let big = make(&jobs, request(150), Values::new()).await;
        let (big_result, big_evaluated) = play(&[&jobs], &big.id).await;
        let seeds = big.values();
        assert_eq!(seeds.len() as u64, big_evaluated);

        // A smaller budget is the larger run's prefix: answered without asking.
        let small = make(&jobs, request(70), seeds.clone()).await;
        let (small_result, evaluated) = play(&[&jobs], &small.id).await;
        assert_eq!(evaluated, 0, "nothing asked");
        let fresh = make(&jobs, request(70), Values::new()).await;
        let (fresh_result, _) = play(&[&jobs], &fresh.id).await;
        assert_eq!(bits(&small_result), bits(&fresh_result), "a prefix is the smaller run's mesh");
        assert_eq!(&bits(&big_result).0[..70], &bits(&small_result).0[..], "in the same order");

        // A larger one asks only for new points, and meshes as a fresh run of its budget.
        let larger = make(&jobs, request(200), seeds).await;
        let (larger_result, evaluated) = play(&[&jobs], &larger.id).await;
        let fresh = make(&jobs, request(200), Values::new()).await;
        let (fresh_result, fresh_evaluated) = play(&[&jobs], &fresh.id).await;
        assert_eq!(bits(&larger_result), bits(&fresh_result));
        assert!(
            evaluated > 0 && evaluated + big_evaluated <= fresh_evaluated + 16,
            "{evaluated} + {big_evaluated} vs {fresh_evaluated}"
        );
        assert!(evaluated < fresh_evaluated / 2, "the told half is not asked again: {evaluated}");

        // Another replica rebuilds a seeded job from its log alone.
        if let Some(bus) = &bus {
            let b = replica(Some(bus), "b");
            let (on_b, asked) = play(&[&b], &larger.id).await;
            assert_eq!((bits(&on_b), asked), (bits(&larger_result), 0));
        }
    }
}
