//! A run's lease on a job, as this replica holds it.

use super::peers::Peers;
use std::sync::Arc;

/// A run's lease on a job.
pub(in crate::jobs) struct Lease {
    /// The run's token, as the lease holds it.
    pub(in crate::jobs) token: String,
    /// Told once the run's first posting is stored.
    pub(in crate::jobs) announced: Option<tokio::sync::oneshot::Sender<()>>,
}

/// Gives a lease back unless disarmed: a submission abandoned between taking a lease and
/// starting its run (its client hung up, or the run was refused) leaves no lease behind.
pub(in crate::jobs) struct LeaseGuard {
    peers: Arc<dyn Peers>,
    id: String,
    token: String,
    armed: bool,
}

impl LeaseGuard {
    /// Guards run `token`'s lease on job `id`, armed when replicas share (a replica alone
    /// takes no lease, and has none to give back).
    pub(super) fn new(peers: &Arc<dyn Peers>, id: &str, token: String) -> Self {
        Self { peers: peers.clone(), id: id.to_owned(), armed: peers.is_shared(), token }
    }

    /// The run's token.
    pub(in crate::jobs) fn token(&self) -> &str {
        &self.token
    }

    /// Keeps the lease: a run now holds it.
    pub(in crate::jobs) fn disarm(&mut self) {
        self.armed = false;
    }
}

impl Drop for LeaseGuard {
    fn drop(&mut self) {
        if let (true, Ok(runtime)) = (self.armed, tokio::runtime::Handle::try_current()) {
            let (peers, id, token) =
                (self.peers.clone(), std::mem::take(&mut self.id), std::mem::take(&mut self.token));
            runtime.spawn(async move { peers.release(&id, &token).await });
        }
    }
}
