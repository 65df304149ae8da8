//! What every handler can reach: the jobs, the limits, the point-location indexes and the
//! bound on large bodies parsed at once.

use crate::config::BodyLimits;
use crate::datasets::Datasets;
use crate::jobs::{ClientJobs, Jobs};
use crate::result::RunResult;
use crate::result::locate::Locator;
use crate::spec::Limits;
use std::sync::{Arc, Weak};

/// Locators of recently evaluated results, each with the result it indexes: a result
/// recomputed under the same id (after a time limit, say) is another mesh, so a hit counts
/// only for the very same result.
pub type Locators = moka::sync::Cache<String, (Weak<RunResult>, Arc<Locator>)>;

/// A locator cache of at most `bytes` bytes.
fn locators(bytes: u64) -> Locators {
    moka::sync::Cache::builder()
        .max_capacity(bytes)
        .weigher(|_: &String, (_, l): &(Weak<RunResult>, Arc<Locator>)| {
            u32::try_from(l.num_bytes()).unwrap_or(u32::MAX)
        })
        .build()
}

/// What every handler can reach.
#[derive(Clone)]
pub struct AppState {
    /// The job registry.
    pub jobs: Jobs,
    /// Jobs whose F the caller evaluates.
    pub clients: ClientJobs,
    /// The DEMs terrain tiles are made of, and the tiles made.
    pub datasets: Datasets,
    /// Whether API keys guard the API: then no shared cache may keep its answers.
    pub keyed: bool,
    /// Request limits.
    pub limits: Limits,
    /// Point-location indexes of results recently evaluated.
    pub locators: Locators,
    /// The size and pace a request body must keep (`extract::Body` reads it).
    pub body: BodyLimits,
    /// Large bodies parsed at once: one fewer than the cores (at least one), so that eight
    /// 256 MiB grids being parsed cannot take every core from the async workers.
    pub parsers: Arc<tokio::sync::Semaphore>,
}

impl AppState {
    /// The state of a server whose point-location indexes take at most `locator_bytes`.
    pub fn new(
        jobs: Jobs,
        datasets: Datasets,
        keyed: bool,
        limits: Limits,
        body: BodyLimits,
        locator_bytes: u64,
    ) -> Self {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let parsers = Arc::new(tokio::sync::Semaphore::new(cores.saturating_sub(1).max(1)));
        let clients = ClientJobs::new(jobs.peers(), limits);
        Self { jobs, clients, datasets, keyed, limits, locators: locators(locator_bytes), body, parsers }
    }
}
