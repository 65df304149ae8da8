//! Jobs: the one bridge between async handlers and the synchronous engine.
//!
//! A submitted [`JobSpec`] gets an id (its canonical hash). A cached result answers at once;
//! a smaller request of a cached run's family is replayed from its trace; an identical job
//! already queued or running is joined; otherwise a new job waits for one of `workers`
//! semaphore permits and then refines on tokio's blocking pool ([`crate::cpu`], at a lower OS
//! priority than the async workers). The tokio docs for `spawn_blocking` recommend exactly
//! this: the blocking pool itself is large, so CPU-bound work needs its own bound.
//!
//! - `job`: a job's state, its outcome, and [`Record`], the one view clients get;
//! - `registry`: [`Jobs`], the table of jobs, the queue bound, the cache and the families;
//! - `share`: each [`Client`]'s share of the workers and the queue;
//! - `budget`: the memory [`Budget`] that bodies and jobs are charged to before they start;
//! - `worker`: one job's run on the blocking pool;
//! - `cache`, `key`, `spec`, `solution`: stored results, ids, and validated requests of meshes
//!   and of boundary value problems.

mod budget;
mod cache;
mod job;
mod key;
mod registry;
mod share;
mod solution;
mod spec;
mod worker;

pub use budget::{Budget, Charge, OverBudget, default_limit as default_memory_bytes};
pub use cache::{Cache, Hit};
pub use job::{Job, JobError, Outcome, Record, Snapshot, Status};
pub use key::{ENGINE_VERSION, JobKeys, job_id, job_keys};
pub use registry::{Found, Jobs, SubmitError, Ticket, Waiter};
pub use share::Client;
pub use solution::{Coef, SolveSpec};
pub use spec::{DEFAULT_MAX_VERTICES, JobSpec, Limits, MeshSpec, SpecError, Work};
