//! Admission: whether a new job may start here (the server is open, the queue has room, the
//! client is within its share, the memory budget holds it), and starting it: its worker and,
//! when it holds a lease, the task that publishes it to the other replicas.

use super::JobSpec;
use super::job::{Job, Lifetime};
use super::replica::publish;
use super::share::{Client, Seat};
use super::state::{Inner, Listing, Start, SubmitError, Ticket};
use super::worker;
use std::sync::Arc;
use std::sync::atomic::Ordering;

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
        let Start { id, family, seq, lease, request } = start;
        let mut table = self.lock();
        // A job followed from elsewhere gives way to the run of the replica holding the lease.
        if let Some(Listing::Live(job)) = table.jobs.get(&id)
            && job.is_joinable()
            && !(lease.is_some() && job.follows)
        {
            self.metrics.cache_misses.inc();
            return Ok((Ticket::Job(self.attach(&table, job, lifetime)), false));
        }
        self.metrics.cache_misses.inc();
        if self.closed.load(Ordering::SeqCst) {
            return Err(SubmitError::ShuttingDown);
        }
        if !self.has_room() {
            let waiting = self.queued();
            return Err(SubmitError::QueueFull { waiting, retry_after: self.retry_after(self.workers) });
        }
        let seat: Seat = self.shares.charge(client).map_err(|held| SubmitError::ShareUsed {
            held,
            retry_after: self.retry_after(self.shares.workers),
        })?;
        let memory = self.budget.charge(spec.memory_bytes()).map_err(|over| {
            self.metrics.memory_refusals.inc();
            SubmitError::OverBudget {
                needed: over.needed,
                available: over.available,
                retry_after: self.retry_after(self.workers),
            }
        })?;
        self.waiting.fetch_add(1, Ordering::SeqCst);
        self.metrics.jobs_queued.inc();
        let job = Arc::new(Job::new(id.clone(), family, lifetime, false, seq));
        let waiter = self.attach(&table, &job, lifetime);
        table.jobs.insert(id, Listing::Live(job.clone()));
        drop(table);
        if let Some(lease) = lease {
            self.publishing.fetch_add(1, Ordering::SeqCst);
            let inner = self.clone();
            let job = job.clone();
            tokio::spawn(async move {
                publish::run(&inner, job, lease, request).await;
                inner.publishing.fetch_sub(1, Ordering::SeqCst);
            });
        }
        tokio::spawn(worker::run(self.clone(), job, spec, (seat, memory)));
        Ok((Ticket::Job(waiter), true))
    }
}
