//! What every part of the registry shares, each part behind its own type: the job table, the
//! admission, the cache and the families in front of it, the metrics, and the link to the
//! other replicas.

use super::Cache;
use super::admission::Admission;
use super::families::Families;
use super::history::History;
use super::replica::peers::Peers;
use super::table::Table;
use crate::metrics::Metrics;
use std::sync::Arc;
use std::sync::atomic::AtomicUsize;

/// The registry's parts. Each owns its state: callers ask them, they do not reach in.
pub(super) struct Inner {
    /// The jobs, live and finished, and who waits on them.
    pub(super) table: Arc<Table>,
    /// Whether a job may start, and its place until a worker takes it.
    pub(super) admission: Admission,
    pub(super) cache: Cache,
    /// Per family, the cached run that answers the most smaller requests.
    pub(super) families: Families,
    pub(super) metrics: Arc<Metrics>,
    /// The other replicas: [`Alone`](super::replica::peers::Alone) until the registry is
    /// [`shared`](super::Jobs::shared).
    pub(super) peers: Arc<dyn Peers>,
    /// A turn per result being read from the store (see `replica::follow::fetch`).
    pub(super) fetching: moka::sync::Cache<String, Arc<tokio::sync::Mutex<()>>>,
    /// Who submitted which job, for the job list.
    pub(super) history: History,
    /// Jobs whose state is still being told to the store: shutdown waits for them too, so that a
    /// job handed back gives up its lease before the process ends.
    pub(super) publishing: AtomicUsize,
}
