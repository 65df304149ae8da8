//! The other replicas, as jobs see them: a store they all share, and the one interface
//! ([`Peers`]) through which this replica's jobs talk to it.
//!
//! The store holds, per job: a lease (which run may run it), the run's [`Posting`] (its state,
//! as `GET /v1/jobs/{id}` shows it), the request it was started from (so that another replica
//! can run it again), what followers asked of the run ([`Control`]), and finished results in
//! compact form. Postings and controls are also sent as [`Message`]s to every replica.
//!
//! What a replica does with these (publish the jobs it runs, follow the ones others run, take
//! over those whose replica died) is decided in `publish`, `follow` and `takeover`, against this
//! interface alone. [`crate::cluster`] implements it over Redis; `alone` for a replica on its
//! own, with no store at all; the tests in memory, several replicas over one bus, with
//! tokio's paused time.

mod alone;
#[cfg(test)]
pub(super) mod memory;
#[cfg(test)]
mod tests;

use crate::api::ProgressEvent;
use crate::result::Summary;
use serde::{Deserialize, Serialize};
use std::time::Duration;
use tokio::sync::broadcast;

pub(in crate::jobs) use alone::Alone;

/// A job's state as the run holding its lease last posted it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Posting {
    /// `queued`, `running`, `succeeded`, `failed` or `cancelled`.
    pub status: String,
    /// Grows with every change, across takeovers too: the id of server-sent events.
    pub seq: u64,
    /// The latest progress report.
    pub progress: Option<ProgressEvent>,
    /// The stats, once succeeded.
    pub stats: Option<Summary>,
    /// Why it failed, once failed.
    pub failure: Option<crate::jobs::Failure>,
    /// How long the engine ran, once finished.
    pub elapsed_ms: Option<f64>,
    /// The token of the run that posted it (see [`Peers::token`]).
    pub run: String,
}

impl Posting {
    /// Whether the job has finished, one way or another.
    pub fn is_final(&self) -> bool {
        matches!(self.status.as_str(), "succeeded" | "failed" | "cancelled")
    }
}

/// A request as a client sent it, kept so that another replica can run the job again.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeptRequest {
    /// `mesh` or `solution`: what the body was read as.
    pub kind: String,
    /// The body's `Content-Type`.
    pub content_type: String,
    /// The body.
    pub body: bytes::Bytes,
}

/// What a follower asks of the run of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Control {
    /// Stop it.
    Cancel,
    /// Run it to the end even if its own clients leave: a client on another replica waits.
    Detach,
}

/// How a run takes a lease.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Take {
    /// For a new submission: the posting of an earlier run and what was asked of it are
    /// dropped (its end is not this run's, and a cancel must not stop a new run).
    Fresh,
    /// For a takeover, or a run taking its lapsed lease again: what is stored stays.
    Over,
}

/// What taking a lease found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Acquired {
    /// This run holds it now.
    Won,
    /// Another run holds it: this token's.
    Held(String),
}

/// A result as the store keeps it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kept {
    /// A run that ended on its own terms: every run of the id makes the same bytes.
    Whole,
    /// A run a time limit stopped: never a new request's answer (another run stops elsewhere).
    Partial,
}

/// A message from a replica (this one included).
#[derive(Debug, Clone)]
pub enum Message {
    /// Job `id` has a new posting.
    Posted(String, Box<Posting>),
    /// The run of job `id` is asked to act.
    Control(String, Control),
}

/// Why the store did not answer: the replica then acts on its own.
#[derive(Debug, Clone, thiserror::Error)]
#[error("the store replicas share did not answer: {0}")]
pub struct Unavailable(pub String);

/// The result of an operation on the store.
pub type Result<T> = std::result::Result<T, Unavailable>;

/// The store the replicas share. Every operation may fail with [`Unavailable`]; none waits
/// long for a store that does not answer.
#[async_trait::async_trait]
pub trait Peers: Send + Sync + 'static {
    /// How long a lease lasts without renewal: how soon another replica takes over a job
    /// whose replica died. The protocol's other clocks follow from it (the lease timing lives
    /// here, in this method and in `renew_every` and `sweep_every`).
    fn lease(&self) -> Duration;

    /// A token for a new run of a job on this replica.
    fn token(&self) -> String;

    /// Whether `token` names a run of this replica.
    fn is_mine(&self, token: &str) -> bool;

    /// Whether other replicas read this store: false for a replica on its own.
    fn is_shared(&self) -> bool;

    /// Whether the last operation reached the store.
    fn is_up(&self) -> bool;

    /// How often a run renews its lease: three times a lease.
    fn renew_every(&self) -> Duration {
        self.lease() / 3
    }

    /// How often each replica looks at the pending jobs (and a follower at the job it
    /// follows): every half lease, and at least every second, so that a job handed back at
    /// shutdown is taken over at once whatever the lease.
    fn sweep_every(&self) -> Duration {
        (self.lease() / 2).clamp(Duration::from_millis(20), Duration::from_secs(1))
    }

    /// Messages from every replica, as they arrive.
    fn messages(&self) -> broadcast::Receiver<Message>;

    /// Checks that the store answers now.
    async fn ping(&self) -> Result<()>;

    /// Takes the lease on job `id` for run `token` if nobody holds it.
    async fn acquire(&self, id: &str, token: &str, take: Take) -> Result<Acquired>;

    /// Extends run `token`'s lease on `id`; false when it no longer holds it.
    async fn renew(&self, id: &str, token: &str) -> Result<bool>;

    /// Gives up run `token`'s lease on `id`, so another may take the job at once.
    async fn release(&self, id: &str, token: &str) -> Result<()>;

    /// The token of the run holding the lease on `id`, if any.
    async fn holder(&self, id: &str) -> Result<Option<String>>;

    /// Stores job `id`'s posting and sends it to every replica, if run `token` holds the
    /// lease, or, for `None`, if no run does (a follower ending a job it found run nowhere);
    /// says whether it did.
    async fn post(&self, id: &str, token: Option<&str>, posting: &Posting) -> Result<bool>;

    /// Job `id`'s posting, if any run stored one (one that does not read, from another
    /// version, counts as none).
    async fn posting(&self, id: &str) -> Result<Option<Posting>>;

    /// Keeps the request of job `id` and lists the job as pending, so that another replica
    /// can take it over; says whether it was kept (not when larger than the store takes).
    async fn keep_request(&self, id: &str, request: &KeptRequest) -> Result<bool>;

    /// The request of job `id`, if kept.
    async fn request(&self, id: &str) -> Result<Option<KeptRequest>>;

    /// The jobs listed as pending.
    async fn pending(&self) -> Result<Vec<String>>;

    /// Whether job `id` is on the pending list (a replica will take it over if its own dies).
    async fn is_pending(&self, id: &str) -> Result<bool>;

    /// Takes job `id` off the pending list and drops its request and what was asked of its
    /// run: it finished.
    async fn forget(&self, id: &str) -> Result<()>;

    /// Asks the run of job `id` to act: a message now, and a mark the run reads at its next
    /// renewal (a message can be missed, a mark cannot).
    async fn control(&self, id: &str, what: Control) -> Result<()>;

    /// Whether a follower asked for job `id` to be cancelled, and to be detached.
    async fn asked(&self, id: &str) -> Result<(bool, bool)>;

    /// The stored result `id` in compact form.
    async fn result(&self, id: &str, kept: Kept) -> Result<Option<Vec<u8>>>;

    /// Stores result `id` in compact form, unless it is larger than the store takes; says
    /// whether it was stored.
    async fn keep_result(&self, id: &str, kept: Kept, bytes: &[u8]) -> Result<bool>;
}
