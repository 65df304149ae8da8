//! Jobs whose F the caller evaluates (ask/tell).
//!
//! A client job holds the points it asked for and the values told, and nothing else between
//! batches: no worker, no engine state, no clock but its lease. When every point of a batch is
//! told, a replay of the refinement over the values on the blocking pool
//! ([`crate::refine::asked`]) names the next batch, or finishes the mesh. The mesh depends on
//! the values alone, never on who told them or when.
//!
//! A batch handed out is leased to whoever asked; unanswered past its lease it is offered again
//! to whoever asks next. A job nobody asks or tells for [`CLIENT_IDLE`] expires (a failed job
//! with a problem saying so), and a finished one is dropped that long after its last word.
//!
//! Every change to a job is an entry of its log (`log`), applied in the log's order. When
//! replicas share a store, an entry is written there before it is applied, and a replica
//! asked for a job it does not hold rebuilds it from the log: so any replica carries on a
//! job another made, and a job outlives the replica that made it. Each replica chooses the
//! batches of the jobs it serves itself (the same values give the same batch everywhere); the
//! first to write a batch's entry hands it out, and a lease holds on the replica that gave it.
//!
//! The files: `job`, one job and the entries that change it; `log`, the entries.

mod job;
mod log;

pub use job::{Asked, CLIENT_IDLE, ClientJob, ClientStatus, TellError};

use super::peers::{Peers, Unavailable};
use crate::api::ClientJobRequest;
use crate::refine::asked::Values;
use crate::spec::{ClientSpec, Limits, is_hex_id};
use log::Entry;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime};

/// The most client jobs a replica keeps, finished ones included.
pub const MAX_CLIENT_JOBS: usize = 256;

/// How long the store keeps a job's log after its last entry: past [`CLIENT_IDLE`], so that a
/// job is not lost to the store before its replica would expire it.
const LOG_KEEP: Duration = Duration::from_secs(2 * 3600);

/// The client jobs of this replica, and those it rebuilt from the store.
#[derive(Clone)]
pub struct ClientJobs {
    jobs: Arc<Mutex<HashMap<String, Arc<ClientJob>>>>,
    made: Arc<AtomicU64>,
    peers: Arc<dyn Peers>,
    /// This replica's limits, which a rebuilt job's request is checked against again.
    limits: Limits,
}

/// Why a client job was not made, or not told.
#[derive(Debug, Clone, PartialEq)]
pub enum ClientError {
    /// [`MAX_CLIENT_JOBS`] are kept already, and none has expired.
    TooMany,
    /// The values cannot be told.
    Tell(TellError),
    /// Replicas share a store and it did not answer: nothing was changed.
    Unreachable,
}

impl From<Unavailable> for ClientError {
    fn from(e: Unavailable) -> Self {
        tracing::warn!(error = %e, "a client job's log could not be written");
        ClientError::Unreachable
    }
}

impl ClientJobs {
    /// The client jobs of a replica that shares its jobs' logs through `peers` (when they are
    /// shared), checking rebuilt requests against `limits`.
    pub fn new(peers: Arc<dyn Peers>, limits: Limits) -> Self {
        Self { jobs: Arc::default(), made: Arc::default(), peers, limits }
    }

    /// A new client job of `spec`, made by `request`, with the values `seeds` told already
    /// (another job's, for a request `from` it): it asks for its corners first, or, seeded,
    /// for what a replay over the seeds does not know.
    ///
    /// # Errors
    /// [`ClientError::TooMany`], or [`ClientError::Unreachable`] when the log cannot be kept.
    pub async fn create(
        &self,
        request: serde_json::Value,
        spec: ClientSpec,
        seeds: Values,
        now: Instant,
    ) -> Result<Arc<ClientJob>, ClientError> {
        {
            let mut jobs = lock(&self.jobs);
            jobs.retain(|_, job| !job.is_stale(now));
            if jobs.len() >= MAX_CLIENT_JOBS {
                return Err(ClientError::TooMany);
            }
        }
        // Not a hash of the request: two callers with the same request run two sessions.
        let made = self.made.fetch_add(1, Ordering::Relaxed);
        let created = SystemTime::now();
        let nanos = created.duration_since(SystemTime::UNIX_EPOCH).unwrap_or_default();
        let id = format!(
            "{:x}",
            Sha256::digest(format!("client {made} {} {}", nanos.as_nanos(), std::process::id()))
        );
        let at_ms = nanos.as_millis() as u64;
        let mut entries = vec![Entry::Made { at_ms, request }];
        if !seeds.is_empty() {
            entries.push(Entry::seeded(&seeds));
        }
        if self.peers.is_shared() {
            let encoded: Vec<Vec<u8>> = entries.iter().map(Entry::encode).collect();
            if self.peers.append_log(&id, 0, &encoded, LOG_KEEP).await?.is_some() {
                // Another replica made this id in the same nanosecond: refuse rather than share.
                return Err(Unavailable(format!("client job id {id} is taken")).into());
            }
        }
        let job = Arc::new(ClientJob::new(id.clone(), spec, created, seeds, entries.len() as u64, now));
        lock(&self.jobs).insert(id, job.clone());
        self.poke(&job);
        Ok(job)
    }

    /// Client job `id` if this replica holds it, as it last heard of it (no store read).
    pub fn local(&self, id: &str) -> Option<Arc<ClientJob>> {
        lock(&self.jobs).get(id).cloned()
    }

    /// Client job `id`, brought up to date with the store's log, or rebuilt from it when this
    /// replica does not hold it; `None` when no replica made it (or its log expired). A
    /// store that does not answer leaves a held job as this replica last heard of it.
    ///
    /// # Errors
    /// [`Unavailable`] for a job this replica does not hold while the store does not answer.
    pub async fn get(&self, id: &str) -> Result<Option<Arc<ClientJob>>, Unavailable> {
        if let Some(job) = self.local(id) {
            if let Err(e) = self.sync(&job).await {
                tracing::debug!(error = %e, job = id, "serving a client job as last heard of");
            }
            return Ok(Some(job));
        }
        if !self.peers.is_shared() || !is_hex_id(id) {
            return Ok(None);
        }
        let log = self.peers.log(id, 0).await?;
        let Some(job) = self.rebuild(id, &log) else { return Ok(None) };
        let job = lock(&self.jobs).entry(id.to_owned()).or_insert(job).clone();
        self.poke(&job);
        Ok(Some(job))
    }

    /// Reads what other replicas wrote to `job`'s log since this one last did, and sets a
    /// replay choosing if the job now waits for one.
    async fn refresh(&self, job: &Arc<ClientJob>) {
        if let Err(e) = self.sync(job).await {
            tracing::debug!(error = %e, job = %job.id, "a client job's log could not be read");
        }
    }

    /// Waits for `changed` (a change to `job` on this replica) until `until`. Another
    /// replica's entries wake nobody here: with a shared store the log is read at least every
    /// sweep meanwhile, and the wait ends after each read, so the caller looks again.
    pub async fn wait(
        &self,
        job: &Arc<ClientJob>,
        changed: std::pin::Pin<&mut tokio::sync::futures::Notified<'_>>,
        until: tokio::time::Instant,
    ) {
        let every = self.peers.is_shared().then(|| self.peers.sweep_every());
        let look = every.map_or(until, |every| until.min(tokio::time::Instant::now() + every));
        if tokio::time::timeout_at(look, changed).await.is_err() {
            self.refresh(job).await;
        }
    }

    /// Tells `values` (id, F or None for a failure) of `job`, all or none: how many were new.
    /// The value completing a batch sets the next one choosing on the blocking pool.
    ///
    /// # Errors
    /// [`ClientError::Tell`] for values that cannot be told (the job is unchanged),
    /// [`ClientError::Unreachable`] when the store does not take them.
    pub async fn tell(
        &self,
        job: &Arc<ClientJob>,
        values: &[(u64, Option<f64>)],
        now: Instant,
    ) -> Result<u64, ClientError> {
        let entry =
            self.commit(job, |job| job.check_tell(values, now).map_err(ClientError::Tell), now).await?;
        self.poke(job);
        Ok(match entry {
            Some(Entry::Told(told)) => told.len() as u64,
            _ => 0,
        })
    }

    /// Cancels `job` unless it has finished: it asks for nothing more, on any replica.
    ///
    /// # Errors
    /// [`ClientError::Unreachable`] when the store does not take the cancellation.
    pub async fn cancel(&self, job: &Arc<ClientJob>, now: Instant) -> Result<(), ClientError> {
        self.commit(job, |job| Ok(job.check_cancel(now)), now).await.map(drop)
    }

    /// Writes the entry `make` gives (if any) to `job`'s log and applies it. When other
    /// replicas wrote entries first, those are applied and `make` asked again, so that its
    /// entry is checked against the job as the log has it.
    async fn commit(
        &self,
        job: &ClientJob,
        make: impl Fn(&ClientJob) -> Result<Option<Entry>, ClientError>,
        now: Instant,
    ) -> Result<Option<Entry>, ClientError> {
        let _writer = job.writer.lock().await;
        loop {
            let Some(entry) = make(job)? else { return Ok(None) };
            if self.peers.is_shared() {
                let written =
                    self.peers.append_log(&job.id, job.applied(), &[entry.encode()], LOG_KEEP).await?;
                if let Some(missed) = written {
                    apply_all(job, &missed, now);
                    continue;
                }
            }
            job.apply(Some(&entry), now);
            return Ok(Some(entry));
        }
    }

    /// Applies what other replicas wrote to `job`'s log since this replica last read it.
    async fn sync(&self, job: &Arc<ClientJob>) -> Result<(), Unavailable> {
        if self.peers.is_shared() {
            let _writer = job.writer.lock().await;
            let missed = self.peers.log(&job.id, job.applied()).await?;
            apply_all(job, &missed, Instant::now());
        }
        self.poke(job);
        Ok(())
    }

    /// Sets a replay choosing `job`'s next batch on the blocking pool, if it waits for one
    /// and none runs here. A batch whose entry cannot be written is chosen again at the next
    /// look at the job.
    fn poke(&self, job: &Arc<ClientJob>) {
        if !job.start_choosing() {
            return;
        }
        let (jobs, job) = (self.clone(), job.clone());
        tokio::spawn(async move {
            let chooser = job.clone();
            match crate::cpu::spawn(move || chooser.choose()).await {
                Ok(Some(batch)) => {
                    let written = jobs.commit(
                        &job,
                        |job| Ok(job.awaits(&batch).then(|| batch.clone())),
                        Instant::now(),
                    );
                    if let Err(e) = written.await {
                        tracing::warn!(error = ?e, job = %job.id, "a client job's next batch could not be written");
                    }
                }
                Ok(None) => {}
                Err(e) => {
                    tracing::error!(error = %e, job = %job.id, "choosing a client job's next batch panicked");
                    job.choosing_failed(format!("choosing the next batch failed on the server: {e}"));
                }
            }
            job.stop_choosing();
        });
    }

    /// Job `id` rebuilt from its whole `log`, if it has one this replica reads.
    fn rebuild(&self, id: &str, log: &[Vec<u8>]) -> Option<Arc<ClientJob>> {
        let (first, rest) = log.split_first()?;
        let Some(Entry::Made { at_ms, request }) = Entry::decode(first) else {
            tracing::warn!(job = id, "a client job's log does not begin as this version's do");
            return None;
        };
        let spec = serde_json::from_value::<ClientJobRequest>(request)
            .map_err(|e| e.to_string())
            .and_then(|request| ClientSpec::from_request(request, &self.limits).map_err(|e| e.to_string()));
        let spec = match spec {
            Ok(spec) => spec,
            Err(e) => {
                tracing::warn!(job = id, error = %e, "a client job from another replica is refused here");
                return None;
            }
        };
        let created = SystemTime::UNIX_EPOCH + Duration::from_millis(at_ms);
        let now = Instant::now();
        let (seeds, rest) = match rest.split_first().map(|(e, rest)| (Entry::decode(e), rest)) {
            Some((Some(Entry::Seeded(seeded)), rest)) => (Entry::seeds(&seeded), rest),
            _ => (Values::new(), rest),
        };
        let applied = (log.len() - rest.len()) as u64;
        let job = Arc::new(ClientJob::new(id.to_owned(), spec, created, seeds, applied, now));
        apply_all(&job, rest, now);
        Some(job)
    }
}

/// Applies `entries`, as the store keeps them, to `job` in order.
fn apply_all(job: &ClientJob, entries: &[Vec<u8>], now: Instant) {
    for bytes in entries {
        let entry = Entry::decode(bytes);
        if entry.is_none() {
            tracing::warn!(job = %job.id, "a client job's log entry does not read: skipped");
        }
        job.apply(entry.as_ref(), now);
    }
}

/// A lock that a panic elsewhere does not poison for everyone else.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(test)]
mod tests;
