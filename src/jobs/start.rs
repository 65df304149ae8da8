//! The start of a run: a job admitted here is listed in the table, given to a worker and,
//! when it holds a lease, to the task that publishes it to the other replicas.

use super::admission::SubmitError;
use super::inner::Inner;
use super::job::{Job, Lifetime};
use super::replica::lease::Lease;
use super::replica::publish;
use super::share::Client;
use super::table::Started;
use super::ticket::Ticket;
use super::worker;
use crate::spec::JobSpec;
use std::sync::Arc;
use std::sync::atomic::Ordering;

/// A new job's id, family and place among the replicas.
pub(super) struct Start {
    pub(super) id: String,
    pub(super) family: String,
    /// Its events are numbered after this (a job taken over continues the numbering).
    pub(super) seq: u64,
    /// The lease this replica holds for the job, if replicas share: the run then publishes
    /// the job's state.
    pub(super) lease: Option<Lease>,
    /// Whether the run keeps the job's spec in the store for a takeover (a job taken over
    /// has it there already).
    pub(super) keep: bool,
}

impl Inner {
    /// Starts a job here, charged to `client`, unless an identical one is live by now; says
    /// whether it started one (which then owns `start.lease`).
    pub(super) fn start(
        self: &Arc<Self>,
        start: Start,
        spec: JobSpec,
        lifetime: Lifetime,
        client: &Client,
    ) -> Result<(Ticket, bool), SubmitError> {
        let Start { id, family, seq, lease, keep } = start;
        self.metrics.cache_misses.inc();
        let mut admitted = None;
        let started = self.table.start(&id, lifetime, lease.is_some(), || {
            let admission =
                self.admission.admit(client, super::budget::memory_bytes(&spec)).inspect_err(|e| {
                    if let SubmitError::OverBudget { .. } = e {
                        self.metrics.memory_refusals.inc();
                    }
                })?;
            admitted = Some(admission);
            self.metrics.jobs_queued.inc();
            Ok(Arc::new(Job::new(id.clone(), family, lifetime, false, seq)))
        })?;
        let (waiter, job) = match started {
            Started::Joined(waiter) => return Ok((Ticket::Job(waiter), false)),
            Started::New(waiter, job) => (waiter, job),
        };
        let admitted = admitted.expect("admitted with the job");
        if let Some(lease) = lease {
            self.publishing.fetch_add(1, Ordering::SeqCst);
            let inner = self.clone();
            let job = job.clone();
            // A clone shares the spec's source and problem.
            let keep = keep.then(|| spec.clone());
            tokio::spawn(async move {
                publish::run(&inner, job, lease, keep).await;
                inner.publishing.fetch_sub(1, Ordering::SeqCst);
            });
        }
        tokio::spawn(worker::run(self.clone(), job, spec, admitted));
        Ok((Ticket::Job(waiter), true))
    }
}
