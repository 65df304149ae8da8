//! Jobs: the one bridge between async handlers and the synchronous engine.
//!
//! A submitted [`JobSpec`] gets an id (its canonical hash). A cached result answers at once;
//! a smaller request of a cached run's family is replayed from its trace; an identical job
//! already queued or running is joined; otherwise a new job waits for one of `workers`
//! workers (handed out by `dispatch`) and then refines on tokio's blocking pool
//! ([`crate::cpu`], at a lower OS priority than the async workers). The tokio docs for `spawn_blocking` recommend exactly
//! this: the blocking pool itself is large, so CPU-bound work needs its own bound.
//!
//! - `job`: a job's state, its outcome, and [`Record`], the one view clients get;
//! - `registry`: [`Jobs`], the table of jobs, the queue bound, the cache and the families;
//! - `share`: each [`Client`]'s share of the workers and the queue;
//! - `dispatch`: the workers, given to waiting jobs so that none idles while a job waits, a
//!   client under its share first;
//! - `budget`: the memory [`Budget`] that bodies and jobs are charged to before they start;
//! - `worker`: one job's run on the blocking pool;
//! - `cache`, `key`, `spec`, `solution`: stored results, ids, and validated requests of meshes
//!   and of boundary value problems.
//! - [`peers`]: the store replicas share, as the one trait [`Peers`](peers::Peers) that jobs
//!   talk to other replicas through, with its wire types (postings, kept requests, controls);
//!   [`crate::cluster`] implements it over Redis, and the tests in memory;
//! - `publish`, `follow`, `takeover`: the replica protocol over that trait: the replica
//!   holding a job's lease publishes it, the others follow it, and a job whose replica died is
//!   run again by the first replica to take its expired lease.

mod budget;
mod cache;
mod dispatch;
mod follow;
mod job;
mod key;
pub mod peers;
mod publish;
mod registry;
mod share;
mod solution;
mod spec;
mod takeover;
mod worker;

pub use budget::{
    Budget, Charge, OverBudget, SOLUTION_BYTES_PER_VERTEX, available_memory, cli_mesh_bytes_per_vertex,
    default_limit as default_memory_bytes,
};
pub use cache::{Cache, Hit};
pub use job::{Job, JobError, Lifetime, Outcome, Record, Snapshot, Status};
pub use key::{ENGINE_VERSION, JobKeys, job_id, job_keys};
pub use registry::{Found, Jobs, SubmitError, Ticket, Waiter};
pub use share::Client;
pub use solution::{Coef, SolveSpec};
pub use spec::{DEFAULT_MAX_VERTICES, JobSpec, Limits, MeshSpec, SpecError, Work};

/// How kept requests are read and problems written when replicas share: the server's own
/// parsing of a request body and its problem documents, given to the registry by the caller.
pub trait Wire: Send + Sync + 'static {
    /// Reads a request another replica kept, as if a client had just sent it here.
    fn parse(
        &self,
        request: peers::KeptRequest,
    ) -> futures_util::future::BoxFuture<'static, Result<(JobKeys, JobSpec), String>>;

    /// The problem document of a job that failed, as clients get it.
    fn problem(&self, error: &JobError) -> serde_json::Value;
}
