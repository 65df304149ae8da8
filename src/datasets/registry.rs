//! [`Datasets`]: the DEMs this server serves tiles of, by id, and the cache of tiles made.

use super::dataset::{Dataset, Origin, digest};
use super::error::DatasetError;
use crate::jobs::peers::{Message, Peers, Shelf, next_message};
use crate::jobs::{Budget, Charge};
use crate::tiles::{Dem, DemError, TileId, Wanted};
use bytes::Bytes;
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError, RwLock, Weak};
use tokio::sync::{Semaphore, broadcast};

/// How datasets are kept and served: the server's settings for them.
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetSettings {
    /// Files served under a name from start-up (`MESHFIT_DATASET`).
    pub files: Vec<(String, PathBuf)>,
    /// Bytes uploaded datasets may hold, files and blocks' caches (`MESHFIT_DATASET_BYTES`).
    pub max_bytes: u64,
    /// Each tile within this fraction of its level's error (`MESHFIT_TILE_ERROR_FACTOR`).
    pub error_factor: f64,
    /// Memory for tiles made, gzipped (`MESHFIT_TILE_CACHE_BYTES`), charged to the budget.
    pub tile_cache_bytes: u64,
}

impl Default for DatasetSettings {
    fn default() -> Self {
        Self { files: Vec::new(), max_bytes: 1 << 30, error_factor: 1.0, tile_cache_bytes: 256 << 20 }
    }
}

/// A tile as cached: gzipped, with its share of the memory budget.
struct Cached {
    gzip: Bytes,
    _charge: Charge,
}

/// A tile's cache key: the dataset's file (the same file named twice in the settings shares
/// its tiles), the tile and its extensions.
type Key = (String, TileId, Wanted);

/// The datasets, shared by every handler.
#[derive(Clone)]
pub struct Datasets {
    inner: Arc<Inner>,
}

struct Inner {
    by_id: RwLock<BTreeMap<String, Arc<Dataset>>>,
    tiles: moka::sync::Cache<Key, Arc<Cached>>,
    budget: Arc<Budget>,
    settings: DatasetSettings,
    /// The store other replicas share uploads and tiles through, if any.
    peers: Option<Arc<dyn Peers>>,
    /// Uploads decoded and tiles made at once: one fewer than the cores (at least one), so
    /// that a map zoomed in on cold tiles cannot take every core from the async workers.
    work: Arc<Semaphore>,
    /// Held while a dataset is read from the store, one lock per id being read.
    fetching: Mutex<BTreeMap<String, Arc<tokio::sync::Mutex<()>>>>,
    /// Uploads deleted on any replica since this one started (until uploaded again): a read
    /// from the store that a deletion overtook does not bring one back.
    dropped: Mutex<BTreeSet<String>>,
}

impl Datasets {
    /// No datasets yet; the files of `settings` are read by [`Datasets::open_files`]. With
    /// `peers`, uploads and tiles are shared with the other replicas, and a dataset deleted on
    /// any of them is dropped here too (so this needs a tokio runtime).
    pub fn new(settings: DatasetSettings, budget: Arc<Budget>, peers: Option<Arc<dyn Peers>>) -> Self {
        let tiles = moka::sync::Cache::builder()
            .max_capacity(settings.tile_cache_bytes)
            .weigher(|_: &Key, tile: &Arc<Cached>| u32::try_from(tile.gzip.len()).unwrap_or(u32::MAX))
            .support_invalidation_closures()
            .build();
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let work = Arc::new(Semaphore::new(cores.saturating_sub(1).max(1)));
        let messages = peers.as_ref().map(|p| p.messages());
        let inner = Arc::new(Inner {
            by_id: RwLock::default(),
            tiles,
            budget,
            settings,
            peers,
            work,
            fetching: Mutex::default(),
            dropped: Mutex::default(),
        });
        if let Some(messages) = messages {
            tokio::spawn(forget_dropped(Arc::downgrade(&inner), messages));
        }
        Self { inner }
    }

    /// The store other replicas share datasets through, if any.
    pub(super) fn peers(&self) -> Option<&Arc<dyn Peers>> {
        self.inner.peers.as_ref()
    }

    /// The bound on uploads decoded and tiles made at once.
    pub(super) fn work(&self) -> &Arc<Semaphore> {
        &self.inner.work
    }

    /// The lock a read of dataset `id` from the store holds. Locks nobody else holds are
    /// dropped as each is handed out, so ids asked for once do not pile up.
    pub(super) fn fetching(&self, id: &str) -> Arc<tokio::sync::Mutex<()>> {
        let mut locks = self.inner.fetching.lock().unwrap_or_else(PoisonError::into_inner);
        locks.retain(|_, lock| Arc::strong_count(lock) > 1);
        locks.entry(id.to_owned()).or_default().clone()
    }

    /// The memory budget.
    pub(super) fn budget(&self) -> &Arc<Budget> {
        &self.inner.budget
    }

    /// Notes that upload `id` was deleted.
    pub(super) fn drop_here(&self, id: &str) {
        self.inner.dropped.lock().unwrap_or_else(PoisonError::into_inner).insert(id.to_owned());
    }

    /// Notes that upload `id` was uploaded again.
    pub(super) fn undrop(&self, id: &str) {
        self.inner.dropped.lock().unwrap_or_else(PoisonError::into_inner).remove(id);
    }

    /// Whether upload `id` was deleted since it was last uploaded.
    pub(super) fn is_dropped(&self, id: &str) -> bool {
        self.inner.dropped.lock().unwrap_or_else(PoisonError::into_inner).contains(id)
    }

    /// Opens each file the settings name and reads it once through: blocking work, done
    /// once at start-up. A file is then read by blocks as tiles need them, never held whole.
    ///
    /// # Errors
    /// The first file that cannot be read or is not a DEM in EPSG:4326, or does not fit the
    /// memory budget, named with its path.
    pub fn open_files(&self) -> Result<(), String> {
        for (name, path) in &self.inner.settings.files {
            let at = || format!("MESHFIT_DATASET: {name}={}", path.display());
            let cannot = |e: std::io::Error| format!("{}: cannot read it: {e}", at());
            let (digest, file_bytes) = file_digest(path).map_err(cannot)?;
            let file = std::fs::File::open(path).map_err(cannot)?;
            let dataset = dem(Box::new(std::io::BufReader::new(file)), usize::MAX)
                .and_then(|dem| self.held(name.clone(), Origin::File(path.clone()), digest, file_bytes, dem))
                .map_err(|e| format!("{}: {e}", at()))?;
            self.write().insert(name.clone(), Arc::new(dataset));
        }
        Ok(())
    }

    /// Adds the DEM in `file` (a GeoTIFF in EPSG:4326 of at most `max_points` samples), or
    /// finds it: its id is the file's hash. True when it is new. CPU work for a large file,
    /// which is read through once. `allowance` counts it against the uploads' allowance: a
    /// file another replica took is served whatever this one's allowance, so that a read
    /// never answers 507.
    ///
    /// # Errors
    /// When the file does not decode, is not such a DEM (or has more tiles than a pyramid
    /// may), or does not fit the datasets' allowance or the memory budget.
    pub(super) fn upload(
        &self,
        file: Bytes,
        max_points: usize,
        allowance: bool,
    ) -> Result<(Arc<Dataset>, bool), DatasetError> {
        let id = digest(&file);
        if let Some(found) = self.get(&id) {
            return Ok((found, false));
        }
        let file_bytes = file.len() as u64;
        let dem = dem(Box::new(std::io::Cursor::new(file)), max_points)?;
        let needed = bytes_of(&dem, file_bytes);
        let dataset = self.held(id.clone(), Origin::Upload, id.clone(), file_bytes, dem)?;
        // Under the lock, so that uploads at once cannot pass the allowance together; of two
        // uploads of one file, the first in is the dataset and the other's charge goes.
        let mut by_id = self.write();
        if let Some(found) = by_id.get(&id) {
            return Ok((found.clone(), false));
        }
        let held: u64 = by_id
            .values()
            .filter(|d| *d.origin() == Origin::Upload)
            .map(|d| bytes_of(d.dem(), d.file_bytes()))
            .sum();
        let limit = self.inner.settings.max_bytes;
        if allowance && held.saturating_add(needed) > limit {
            return Err(DatasetError::Full { needed, held, limit });
        }
        let dataset = Arc::new(dataset);
        by_id.insert(id, dataset.clone());
        Ok((dataset, true))
    }

    /// The dataset `id`.
    pub fn get(&self, id: &str) -> Option<Arc<Dataset>> {
        self.inner.by_id.read().unwrap_or_else(PoisonError::into_inner).get(id).cloned()
    }

    /// Every dataset, by id.
    pub fn list(&self) -> Vec<Arc<Dataset>> {
        self.inner.by_id.read().unwrap_or_else(PoisonError::into_inner).values().cloned().collect()
    }

    /// Removes the uploaded dataset `id` and its cached tiles from this replica.
    ///
    /// # Errors
    /// When there is none here, or it is a file the settings name.
    pub(super) fn remove(&self, id: &str) -> Result<(), DatasetError> {
        let mut by_id = self.write();
        match by_id.get(id).map(|d| d.origin()) {
            None => return Err(DatasetError::NotFound { id: id.to_owned(), shared: false }),
            Some(Origin::File(_)) => return Err(DatasetError::Configured(id.to_owned())),
            Some(Origin::Upload) => {}
        }
        let removed = by_id.remove(id).expect("looked up under the same lock");
        drop(by_id);
        let digest = removed.digest().to_owned();
        // Only fails when the cache was built without closures, which it is not.
        let _ = self.inner.tiles.invalidate_entries_if(move |(d, _, _), _| *d == digest);
        Ok(())
    }

    /// The cached gzip of `tile` of `dataset` with `wanted`, if it was made lately.
    pub(super) fn cached(&self, dataset: &Dataset, tile: TileId, wanted: Wanted) -> Option<Bytes> {
        let key = (dataset.digest().to_owned(), tile, wanted);
        self.inner.tiles.get(&key).map(|c| c.gzip.clone())
    }

    /// Makes `tile` of `dataset` with `wanted`, gzipped, and caches it. CPU work: tens of
    /// milliseconds, more for a deep tile of a fine DEM.
    ///
    /// # Errors
    /// [`DatasetError::NoTile`] when the dataset's pyramid has no such tile.
    pub(super) fn make(
        &self,
        dataset: &Dataset,
        tile: TileId,
        wanted: Wanted,
    ) -> Result<Bytes, DatasetError> {
        let pyramid = dataset.pyramid();
        let bytes = pyramid
            .tile(tile, wanted)
            .map_err(|e| DatasetError::Unreadable { id: dataset.id().to_owned(), detail: e.to_string() })?
            .ok_or_else(|| DatasetError::NoTile(not_available(dataset, tile)))?;
        let gzip = Bytes::from(gzip(&bytes));
        self.keep(dataset, tile, wanted, gzip.clone());
        Ok(gzip)
    }

    /// Caches a tile's gzip, if the memory budget has room.
    pub(super) fn keep(&self, dataset: &Dataset, tile: TileId, wanted: Wanted, gzip: Bytes) {
        if let Ok(charge) = self.inner.budget.charge(gzip.len() as u64) {
            let key = (dataset.digest().to_owned(), tile, wanted);
            self.inner.tiles.insert(key, Arc::new(Cached { gzip, _charge: charge }));
        }
    }

    /// Says why `tile` is not one `dataset` serves, or nothing when it is.
    pub fn check(&self, dataset: &Dataset, tile: TileId) -> Result<(), DatasetError> {
        if dataset.pyramid().has(tile) {
            Ok(())
        } else {
            Err(DatasetError::NoTile(not_available(dataset, tile)))
        }
    }

    /// A dataset of `dem`, from a file of `file_bytes` whose SHA-256 is `digest`, with its
    /// heights charged to the memory budget for as long as it is held.
    fn held(
        &self,
        id: String,
        origin: Origin,
        digest: String,
        file_bytes: u64,
        dem: Dem,
    ) -> Result<Dataset, DatasetError> {
        let held = if origin == Origin::Upload { file_bytes } else { 0 };
        let charge = self.inner.budget.charge(bytes_of(&dem, held)).map_err(DatasetError::OverBudget)?;
        Dataset::new(id, origin, digest, file_bytes, dem, self.inner.settings.error_factor, charge)
    }

    fn write(&self) -> std::sync::RwLockWriteGuard<'_, BTreeMap<String, Arc<Dataset>>> {
        self.inner.by_id.write().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Drops, on this replica, each dataset another replica deleted, until the datasets are gone.
async fn forget_dropped(inner: Weak<Inner>, mut messages: broadcast::Receiver<Message>) {
    while let Some(message) = next_message(&mut messages).await {
        let Some(inner) = inner.upgrade() else { return };
        if let Message::Dropped(Shelf::Dataset, id) = message {
            let datasets = Datasets { inner };
            datasets.drop_here(&id);
            // Not here, or a file named in this replica's settings: nothing to drop.
            if datasets.remove(&id).is_ok() {
                tracing::info!(dataset = %id, "dataset deleted on another replica");
            }
        }
    }
}

/// The DEM in `file`, of at most `max_points` samples.
fn dem(file: Box<dyn crate::source::BlockReader>, max_points: usize) -> Result<Dem, DatasetError> {
    Dem::open(file, max_points).map_err(|e| match e {
        DemError::File(e) => DatasetError::File(e),
        e => DatasetError::Dem(e),
    })
}

/// The memory a DEM takes: its blocks' cache and masks, and `file_bytes` of its file held.
fn bytes_of(dem: &Dem, file_bytes: u64) -> u64 {
    dem.resident_bytes() + file_bytes
}

/// The SHA-256 of the file at `path`, hex, and its length: read through, never held.
fn file_digest(path: &std::path::Path) -> std::io::Result<(String, u64)> {
    use sha2::Digest;
    let mut hash = sha2::Sha256::new();
    let bytes = std::io::copy(&mut std::fs::File::open(path)?, &mut hash)?;
    Ok((format!("{:x}", hash.finalize()), bytes))
}

/// `bytes` gzipped, as a client that sends `Accept-Encoding: gzip` takes them.
fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder =
        flate2::write::GzEncoder::new(Vec::with_capacity(bytes.len() / 2), flate2::Compression::default());
    encoder.write_all(bytes).expect("writing to a Vec");
    encoder.finish().expect("writing to a Vec")
}

/// Why `tile` is not served, with the tiles its level has.
fn not_available(dataset: &Dataset, tile: TileId) -> String {
    let TileId { z, x, y } = tile;
    match dataset.pyramid().available(z) {
        Some(([x0, x1], [y0, y1])) if (x0..=x1).contains(&x) && (y0..=y1).contains(&y) => format!(
            "tile {z}/{x}/{y} is not available: it holds only nodata samples of dataset `{}`",
            dataset.id()
        ),
        Some(([x0, x1], [y0, y1])) => format!(
            "tile {z}/{x}/{y} is not available: level {z} of dataset `{}` has x in {x0}..={x1} and y in {y0}..={y1}",
            dataset.id()
        ),
        None => format!(
            "tile {z}/{x}/{y} is not available: dataset `{}` has levels 0..={}",
            dataset.id(),
            dataset.max_level()
        ),
    }
}
