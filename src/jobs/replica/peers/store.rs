//! The store the replicas share, as the one trait [`Peers`] this replica's jobs talk to it
//! through, and why an operation on it failed.

use super::wire::{Acquired, Asked, Control, Kept, Message, Posting, Shelf, Take};
use std::time::Duration;
use tokio::sync::broadcast;

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

    /// Keeps the spec of job `id`, in its canonical encoding ([`crate::spec::canonical`]),
    /// and lists the job as pending, so that another replica can take it over; says whether
    /// it was kept (not when larger than the store takes).
    async fn keep_spec(&self, id: &str, spec: &[u8]) -> Result<bool>;

    /// The spec of job `id`, if kept.
    async fn kept_spec(&self, id: &str) -> Result<Option<Vec<u8>>>;

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

    /// What followers asked of the run of job `id`.
    async fn asked(&self, id: &str) -> Result<Asked>;

    /// The stored result `id` in compact form.
    async fn result(&self, id: &str, kept: Kept) -> Result<Option<Vec<u8>>>;

    /// Stores result `id` in compact form, unless it is larger than the store takes; says
    /// whether it was stored.
    async fn keep_result(&self, id: &str, kept: Kept, bytes: &[u8]) -> Result<bool>;

    /// Keeps file `id` on `shelf`, unless it is larger than the store takes; says whether it
    /// was kept. A dataset is kept until it is dropped, a tile for the store's time to live.
    async fn keep_file(&self, shelf: Shelf, id: &str, bytes: &[u8]) -> Result<bool>;

    /// File `id` on `shelf`, if kept; reading a tile starts its time to live again.
    async fn file(&self, shelf: Shelf, id: &str) -> Result<Option<Vec<u8>>>;

    /// Drops file `id` from `shelf` and tells every replica ([`Message::Dropped`]).
    async fn drop_file(&self, shelf: Shelf, id: &str) -> Result<()>;

    /// Appends `entries` to log `id` if it holds exactly `at` entries (`None`: appended),
    /// else appends nothing and answers the entries from `at` on, which the caller missed.
    /// The log is dropped `keep` after its last append.
    async fn append_log(
        &self,
        id: &str,
        at: u64,
        entries: &[Vec<u8>],
        keep: Duration,
    ) -> Result<Option<Vec<Vec<u8>>>>;

    /// Log `id`'s entries from `from` on: none when there is no such log.
    async fn log(&self, id: &str, from: u64) -> Result<Vec<Vec<u8>>>;
}
