//! What replicas exchange through the store: a job's [`Posting`], what a follower asks of a
//! run, how a lease is taken and what that found, how a
//! result is kept, and the messages every replica receives.

use crate::api::ProgressEvent;
use crate::jobs::Failure;
use crate::result::Summary;
use serde::{Deserialize, Serialize};

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
    pub failure: Option<Failure>,
    /// How long the engine ran, once finished.
    pub elapsed_ms: Option<f64>,
    /// The token of the run that posted it (see [`Peers::token`](super::Peers::token)).
    pub run: String,
}

impl Posting {
    /// Whether the job has finished, one way or another.
    pub fn is_final(&self) -> bool {
        matches!(self.status.as_str(), "succeeded" | "failed" | "cancelled")
    }
}

/// What a follower asks of the run of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Control {
    /// Stop it.
    Cancel,
    /// Run it to the end even if its own clients leave: a client on another replica waits.
    Detach,
}

/// What followers asked of a run, marked in the store for its next renewal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Asked {
    /// Stop it.
    pub cancel: bool,
    /// Run it to the end even if its own clients leave.
    pub detach: bool,
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
    /// File `id` was dropped from a shelf: replicas holding a copy drop theirs.
    Dropped(Shelf, String),
}

/// Files the store keeps beside jobs, which any replica may need.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Shelf {
    /// An uploaded dataset's file, by the dataset's id.
    Dataset,
    /// A terrain tile, gzipped, by its entity tag.
    Tile,
}

impl Shelf {
    /// Its name in keys and messages.
    pub fn name(self) -> &'static str {
        match self {
            Shelf::Dataset => "dataset",
            Shelf::Tile => "tile",
        }
    }

    /// The shelf named `name`.
    pub fn named(name: &str) -> Option<Shelf> {
        [Shelf::Dataset, Shelf::Tile].into_iter().find(|s| s.name() == name)
    }
}

/// The next message for a replica's listener: one missed while it lagged is skipped (postings
/// are read back at the next sweep, requests from their keys, drops from the store), `None`
/// once no replica sends any more.
pub async fn next_message(messages: &mut tokio::sync::broadcast::Receiver<Message>) -> Option<Message> {
    use tokio::sync::broadcast::error::RecvError;
    loop {
        match messages.recv().await {
            Ok(message) => return Some(message),
            Err(RecvError::Lagged(_)) => continue,
            Err(RecvError::Closed) => return None,
        }
    }
}
