//! Replicas that share results and jobs through Redis (`MESHFIT_REDIS_URL`).
//!
//! This module is the transport: [`Cluster`] implements [`Peers`](crate::jobs::peers::Peers), the store that
//! [`crate::jobs`] shares with the other replicas, in Redis keys, scripts and channels. What a
//! replica does with it (follow a job another replica runs, take over one whose replica died)
//! is decided in `jobs`, which knows nothing of Redis.
//!
//! redis-rs rather than a hand-written client: its `ConnectionManager` multiplexes commands
//! over one connection (a replica keeps two: small commands, and results and specs) and
//! reconnects by itself after Redis comes back, which is exactly the behaviour a replica
//! needs when Redis goes away.
//!
//! | key | holds | expires |
//! |---|---|---|
//! | `meshfit:result:{id}` | a finished result, compact and checksummed | `MESHFIT_REDIS_TTL_MS` |
//! | `meshfit:partial:{id}` | a result a time limit stopped (never a new request's answer) | same |
//! | `meshfit:job:{id}` | the job's [`Posting`](crate::jobs::peers::Posting) as JSON | same |
//! | `meshfit:lease:{id}` | the token of the run holding it: replica and run number | `MESHFIT_REDIS_LEASE_MS`, renewed |
//! | `meshfit:spec:{id}` | the job's spec in canonical form ([`crate::spec::canonical`]), so another replica can take the job over | same as results |
//! | `meshfit:pending` | ids of jobs not finished, with a stored spec | |
//! | `meshfit:cancel:{id}`, `meshfit:detach:{id}` | asked of the run by a replica that follows it | three leases |
//! | `meshfit:log:{id}` | a client job's log, a list of JSON entries appended by a script only at the length the writer read | two hours after the last entry |
//!
//! Only the run holding the lease writes the job's posting (a script checks the token), so a
//! run that lost its lease cannot overwrite its successor's. Postings go out on the channel
//! `meshfit:events` as they are written; `meshfit:control` carries `cancel {id}` and
//! `detach {id}` to the replica that runs the job, and the keys of the same names keep the
//! request for the run's next renewal in case the message is missed.

mod client;
mod keys;
mod link;
mod listen;

pub use client::Cluster;
