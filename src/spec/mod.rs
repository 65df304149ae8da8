//! Requests as the engine takes them: the wire's request types checked against the server's
//! [`Limits`] (none on the command line) and mapped to domain types, whose own constructors
//! hold the engine's rules ([`crate::refine::ParamsBuilder`], [`crate::solve::Polygon::try_new`],
//! [`crate::solve::Region::try_new`]), as a canonical [`JobSpec`] with its id.
//!
//! - `checks`: the server's [`Limits`], and [`SpecError`], which names the request field at
//!   fault;
//! - `job`: [`JobSpec`], a mesh ([`MeshSpec`]) or a solution, from a JSON request or an
//!   uploaded grid file;
//! - `solution`: [`SolveSpec`], a boundary value problem;
//! - `client`: [`ClientSpec`], a refinement whose F the caller evaluates (ask/tell);
//! - `canonical`: a spec's canonical encoding, which its id hashes and replicas keep, and
//!   the decoding of a kept one against this server's limits;
//! - `key`: a spec's canonical hash, the job's id, under [`ENGINE_VERSION`].

pub mod canonical;
mod checks;
mod client;
mod job;
mod key;
mod solution;

pub use crate::solve::materials;
pub use canonical::ENGINE_VERSION;
pub use checks::{DEFAULT_MAX_VERTICES, Limits, SpecError, grid_error};
pub use client::{
    ClientSpec, DEFAULT_BATCH, DEFAULT_LEASE, LEASE_MS, MAX_BATCH, MAX_CLIENT_VERTICES, VERTICES_PER_BATCH,
};
pub use job::{JobSpec, MeshSpec, Work};
pub use key::{JobKeys, is_hex_id, job_id, job_keys};
pub use solution::{Function, SolveSpec};
