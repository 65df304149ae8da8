//! The connections to Redis a replica holds, and whether Redis answered the last command.

use crate::config::Redis;
use crate::jobs::peers::{Message, Result, Unavailable};
use redis::aio::ConnectionManager;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use tokio::sync::broadcast;

/// What every task of a replica shares of its Redis.
pub(super) struct Inner {
    /// Leases, postings, messages and the ping: small commands that must not wait.
    pub(super) conn: ConnectionManager,
    /// Results and specs, up to `max_bytes` each: on a connection of their own, so that a
    /// large transfer never holds a lease renewal or the ping back (a ping held past its
    /// timeout would take Redis for gone).
    pub(super) bulk: ConnectionManager,
    pub(super) settings: Redis,
    /// This replica's name in leases: host, process and start time.
    pub(super) replica: String,
    /// Numbers this replica's runs, for their tokens.
    pub(super) runs: AtomicU64,
    /// Whether the last command reached Redis.
    pub(super) up: AtomicBool,
    pub(super) errors: prometheus_client::metrics::counter::Counter,
    pub(super) messages: broadcast::Sender<Message>,
}

impl Inner {
    /// Notes a command's outcome: Redis is up after an answer, down after a failure to reach
    /// it. An error Redis itself answered (out of memory, say) leaves it up: it is there; so
    /// does a slow answer to a large transfer (only the ping's timeout says Redis is gone).
    pub(super) fn note<T>(&self, result: redis::RedisResult<T>) -> Result<T> {
        match result {
            Ok(value) => {
                if !self.up.swap(true, Ordering::Relaxed) {
                    tracing::info!("redis reachable");
                }
                Ok(value)
            }
            Err(e)
                if (e.is_io_error() && !e.is_timeout())
                    || e.is_connection_dropped()
                    || e.is_connection_refusal()
                    || e.is_unrecoverable_error() =>
            {
                Err(self.unreachable(e))
            }
            Err(e) => {
                self.errors.inc();
                tracing::warn!(error = %e, "redis command failed");
                Err(Unavailable(e.to_string()))
            }
        }
    }

    /// Notes that Redis cannot be reached: commands fail at once until it answers again.
    pub(super) fn unreachable(&self, e: redis::RedisError) -> Unavailable {
        self.errors.inc();
        if self.up.swap(false, Ordering::Relaxed) {
            tracing::warn!(error = %e, "redis unreachable; serving from this replica alone");
        }
        Unavailable(e.to_string())
    }
}
