//! What a submission found or started.

use super::job::JobError;
use super::table::Waiter;
use crate::result::RunResult;
use std::sync::Arc;

/// What a submission found or started.
pub enum Ticket {
    /// The result was cached.
    Cached(Arc<RunResult>),
    /// The result was replayed from a larger cached run of the same family, without F.
    Prefix(Arc<RunResult>),
    /// A job, new or already under way, with this client registered as waiting on it (for a
    /// detached submission, the registration is dropped at once and changes nothing).
    Job(Waiter),
    /// An identical job failed on its input before; it would fail the same way again.
    Failed(JobError),
}
