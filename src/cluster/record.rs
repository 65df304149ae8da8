//! A job's state as replicas exchange it: what `GET /v1/jobs/{id}` shows, in JSON.

use crate::api::ProgressEvent;
use crate::result::Summary;
use serde::{Deserialize, Serialize};

/// A job's state as the replica running it last stored it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// `queued`, `running`, `succeeded`, `failed` or `cancelled`.
    pub status: String,
    /// Grows with every change, across takeovers too: the id of server-sent events.
    pub seq: u64,
    /// The latest progress report.
    pub progress: Option<ProgressEvent>,
    /// The stats, once succeeded.
    pub stats: Option<Summary>,
    /// The problem document, once failed.
    pub problem: Option<serde_json::Value>,
    /// How long the engine ran, once finished.
    pub elapsed_ms: Option<f64>,
    /// The token of the run that stored it (see [`super::Cluster::token`]).
    pub run: String,
}

impl Record {
    /// Whether the job has finished, one way or another.
    pub fn is_final(&self) -> bool {
        matches!(self.status.as_str(), "succeeded" | "failed" | "cancelled")
    }
}
