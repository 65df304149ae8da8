//! The replica protocol: how replicas that share a store decide who runs a job, and how the
//! others hear of it.
//!
//! - [`peers`]: the store replicas share, as the one trait [`Peers`](peers::Peers) that jobs
//!   talk to other replicas through, with its wire types (postings, controls);
//!   [`crate::cluster`] implements it over Redis, `peers::alone` for a replica on its own
//!   (no store: every operation fails as if the store were away, and the replica acts
//!   alone, as it does then), and the tests in memory;
//! - `lease`: a run's lease as this replica holds it, and the guard that gives it back;
//! - `claim`: who runs a job, decided in one call, `claim(id)` →
//!   `Claim::{Run, Follow, Alone}` (or `Joined`, when a run of this replica has it);
//! - `publish`, `follow`, `takeover`: the replica holding a job's lease publishes it, the
//!   others follow it, and a job whose replica died is run again by the first replica to
//!   take its expired lease, from its kept spec ([`crate::spec::canonical`]).

pub(super) mod claim;
pub(super) mod follow;
pub(super) mod lease;
pub mod peers;
pub(super) mod publish;
pub(super) mod takeover;
