//! Jobs: the one bridge between async handlers and the synchronous engine.
//!
//! A submitted [`JobSpec`] gets an id (its canonical hash). A cached result answers at once;
//! a smaller request of a cached run's family is replayed from its trace; an identical job
//! already queued or running is joined; otherwise a new job waits for one of `workers`
//! workers (handed out by `dispatch`) and then refines on tokio's blocking pool
//! ([`crate::cpu`], at a lower OS priority than the async workers). The tokio docs for
//! `spawn_blocking` recommend exactly this: the blocking pool itself is large, so CPU-bound
//! work needs its own bound.
//!
//! The files, in the order data flows through them (none imports one below it that imports
//! it back):
//! - `checks`, `spec`, `solution`, `key`: a request checked against the server's [`Limits`]
//!   ([`SpecError`] names the field at fault), as a canonical [`JobSpec`] of a mesh or of a
//!   boundary value problem, and its id;
//! - `failure`: why a job failed as data ([`Failure`]), the same whichever replica ran it;
//! - `job`: a job's state, its outcome, and [`Record`], the one view clients get;
//! - `state`: the job table behind its lock (functions that need the lock take its guard),
//!   the waiters, and what every part below shares;
//! - `admit`: admission (shutdown, the queue's bound, each [`Client`]'s share from `share`,
//!   the memory [`Budget`] from `budget`, `Retry-After`) and the start of a run;
//! - `dispatch`: the workers, given to waiting jobs so that none idles while a job waits, a
//!   client under its share first;
//! - `worker`: one job's run on the blocking pool;
//! - `cache`: stored results, in memory and on disk;
//! - `registry`: [`Jobs`], the one public face: submit, find, watch, cancel, shut down.
//! - `replica`: the replica protocol, in its own folder: [`peers`], the store replicas
//!   share, as the one trait [`Peers`](peers::Peers) that jobs talk to other replicas
//!   through, with its wire types (postings, kept requests, controls); [`crate::cluster`]
//!   implements it over Redis, `peers::alone` for a replica on its own (no store: every
//!   operation fails as if the store were away, and the replica acts alone, as it does
//!   then), and the tests in memory; and `publish`, `follow`, `takeover`: the replica
//!   holding a job's lease publishes it, the others follow it, and a job whose replica died
//!   is run again by the first replica to take its expired lease, from its request as a
//!   [`RequestParser`] reads it.

mod admit;
mod budget;
mod cache;
mod checks;
mod dispatch;
mod failure;
mod job;
mod key;
mod registry;
mod replica;
mod share;
mod solution;
mod spec;
mod state;
mod worker;

pub use budget::{
    Budget, Charge, OverBudget, SOLUTION_BYTES_PER_VERTEX, available_memory, cli_mesh_bytes_per_vertex,
    default_limit as default_memory_bytes,
};
pub use cache::{Cache, CacheSettings, Hit};
pub use checks::{DEFAULT_MAX_VERTICES, Limits, SpecError};
pub use failure::{Cause, Failure};
pub use job::{Job, JobError, Lifetime, Outcome, Record, Snapshot, Status};
pub use key::{ENGINE_VERSION, JobKeys, job_id, job_keys};
pub use registry::{Found, Jobs, Pool};
pub use replica::{RequestParser, peers};
pub use share::Client;
pub use solution::{Coef, SolveSpec};
pub use spec::{JobSpec, MeshSpec, Work};
pub use state::{SubmitError, Ticket, Waiter};
