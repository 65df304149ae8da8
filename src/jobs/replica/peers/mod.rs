//! The other replicas, as jobs see them: a store they all share, and the one interface
//! ([`Peers`]) through which this replica's jobs talk to it.
//!
//! The store holds, per job: a lease (which run may run it), the run's [`Posting`] (its state,
//! as `GET /v1/jobs/{id}` shows it), its spec in canonical form (so that another replica can
//! run it again), what followers asked of the run ([`Control`]), and finished results in
//! compact form. Postings and controls are also sent as [`Message`]s to every replica. Beside
//! jobs it keeps files on [`Shelf`]s: uploaded datasets and the terrain tiles made of them.
//!
//! What a replica does with these (publish the jobs it runs, follow the ones others run, take
//! over those whose replica died) is decided in `publish`, `follow` and `takeover`, against this
//! interface alone. [`crate::cluster`] implements it over Redis; `alone` for a replica on its
//! own, with no store at all; the tests in memory, several replicas over one bus, with
//! tokio's paused time.
//!
//! The files: `wire`, what replicas exchange through the store ([`Posting`], [`Control`],
//! …); `store`, the trait [`Peers`] and [`Unavailable`]; `alone`, `memory` (for
//! the tests), its implementations here; `tests`, the protocol's tests in memory.

mod alone;
#[cfg(test)]
pub(in crate::jobs) mod memory;
mod store;
#[cfg(test)]
mod tests;
mod wire;

pub(in crate::jobs) use alone::Alone;
pub use store::{Peers, Result, Unavailable};
pub use wire::{Acquired, Asked, Control, Kept, Message, Posting, Shelf, Take, next_message};
