//! Jobs: the one bridge between async handlers and the synchronous engine.
//!
//! A submitted [`JobSpec`](crate::spec::JobSpec) (made by [`crate::spec`]) gets an id (its
//! canonical hash). A cached result answers at once; a smaller request of a cached run's
//! family is replayed from its trace; an identical job already queued or running is joined;
//! otherwise a new job waits for one of `workers` workers (handed out by `dispatch`) and then
//! refines on tokio's blocking pool ([`crate::cpu`], at a lower OS priority than the async workers). The tokio docs for
//! `spawn_blocking` recommend exactly this: the blocking pool itself is large, so CPU-bound
//! work needs its own bound.
//!
//! The files, in the order data flows through them (none imports one below it that imports
//! it back):
//! - `failure`: why a job failed as data ([`Failure`]), the same whichever replica ran it;
//! - `job`: one job: its lifecycle ([`Status`], changed only by the job's own methods), its
//!   stop request, its clients (counted under the table's lock), its outcome, and
//!   [`Record`], the one view clients get;
//! - `table`: the job table, which owns its state (mini-redis's `Db`): its map is private,
//!   its lock taken only in its own methods, which callers ask (`join`, `start`, `follow`,
//!   `file`, `stop_all`, …); and [`Waiter`], a client waiting on a job;
//! - `admission`: `Admission` as one type: shutdown, the queue's bound, each
//!   [`Client`]'s share (from `share`), the workers handed out by `dispatch` (a client under
//!   its share first, so that none idles while a job waits), the memory [`Budget`] (from
//!   `budget`), and `Retry-After`: where a scheduler changes who runs and who waits;
//! - `cache`: stored results, in memory and on disk; `families`: per family, the cached run
//!   that answers smaller requests by replay;
//! - `inner`: the parts above that the registry is made of, shared by everything below;
//! - `worker`: one job's run on the blocking pool; `start`: a job admitted, listed in the
//!   table, given to a worker and, when it holds a lease, to `replica::publish`;
//! - `replica`: the replica protocol, in its own folder: [`peers`], the store
//!   replicas share as the one trait [`Peers`](peers::Peers) (with its wire types;
//!   [`crate::cluster`] implements it over Redis, `peers::alone` for a replica on its own,
//!   the tests in memory); `claim`, who runs a job, in one call
//!   (`Claim::{Run, Follow, Alone}`); `lease`; and `publish`, `follow`, `takeover`: the
//!   replica holding a job's lease publishes it, the others follow it, and a job whose
//!   replica died is run again by the first replica to take its expired lease;
//! - `ticket`: what a submission found or started ([`Ticket`]); `submit`: a submission, a
//!   small function per step (cache hit, prefix replay, join, claim, remote fetch);
//! - `history`: who submitted which job and when, for the job list;
//! - `registry`: [`Jobs`], the one public face: submit, find, list, watch, cancel, shut down;
//! - `client`: [`ClientJobs`], jobs whose F the caller evaluates (ask/tell), apart from the
//!   rest: they hold no worker, and the engine runs only when a batch of values is complete;
//!   shared, their logs in the store let any replica carry them on.

mod admission;
mod budget;
mod cache;
mod client;
mod dispatch;
mod failure;
mod families;
mod history;
mod inner;
mod job;
mod registry;
mod replica;
mod share;
mod start;
mod submit;
mod table;
mod ticket;
mod worker;

pub use admission::{Pool, SubmitError};
pub use budget::{
    Budget, Charge, GRID_BYTES_PER_POINT, OverBudget, SOLUTION_BYTES_PER_VERTEX, available_memory,
    cli_mesh_bytes_per_vertex, default_limit as default_memory_bytes,
};
pub use cache::{Cache, CacheSettings, Hit};
pub use client::{
    Asked, CLIENT_IDLE, ClientError, ClientJob, ClientJobs, ClientStatus, MAX_CLIENT_JOBS, TellError,
};
pub use failure::{Cause, Failure};
pub use history::{SUBMISSIONS_KEPT, Submission};
pub use job::{Job, JobError, Lifetime, Outcome, Record, Snapshot, Status, Times};
pub use registry::{Found, Jobs};
pub use replica::peers;
pub use share::Client;
pub use table::Waiter;
pub use ticket::Ticket;
