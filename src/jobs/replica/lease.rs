//! A run's lease on a job, as this replica holds it.

/// A run's lease on a job.
pub(in crate::jobs) struct Lease {
    /// The run's token, as the lease holds it.
    pub(in crate::jobs) token: String,
    /// Told once the run's first posting is stored.
    pub(in crate::jobs) announced: Option<tokio::sync::oneshot::Sender<()>>,
}
