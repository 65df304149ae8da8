//! The datasets as a client of any replica sees them. An upload is kept in the store replicas
//! share (up to `MESHFIT_REDIS_MAX_BYTES`), so another replica asked for it reads it once and
//! serves it as its own; each tile made is kept there too, so a tile is made once for all
//! replicas; a dataset deleted on one is dropped from the store and, by a message, from every
//! replica holding it. Without a store, or while it does not answer, a replica serves what it
//! holds.

use super::dataset::Dataset;
use super::error::DatasetError;
use super::registry::Datasets;
use crate::jobs::peers::Shelf;
use crate::tiles::{TileId, Wanted};
use bytes::Bytes;
use std::sync::Arc;

/// A dataset added.
pub struct Added {
    /// The dataset.
    pub dataset: Arc<Dataset>,
    /// False when the same file was a dataset already.
    pub created: bool,
    /// Whether other replicas can serve it: `None` without a store, `Some(false)` when the
    /// file is larger than the store keeps or the store did not answer.
    pub shared: Option<bool>,
}

/// Where a tile's bytes came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Made {
    /// This replica's cache.
    Hit,
    /// The store: another replica made it.
    Shared,
    /// Made for this request.
    Miss,
}

impl Made {
    /// Its name in `X-Cache`.
    pub fn name(self) -> &'static str {
        match self {
            Made::Hit => "hit",
            Made::Shared => "shared",
            Made::Miss => "miss",
        }
    }
}

impl Datasets {
    /// Adds the DEM in `file` (at most `max_points` samples), or finds it, and keeps the file
    /// for the other replicas.
    ///
    /// # Errors
    /// When the file does not decode, is not a DEM in EPSG:4326, or does not fit the datasets'
    /// allowance or the memory budget.
    pub async fn add(&self, file: Bytes, max_points: usize) -> Result<Added, DatasetError> {
        let (dataset, created) = self.decode(file.clone(), max_points, true).await?;
        self.undrop(dataset.id());
        let shared = match self.peers() {
            Some(peers) => Some(peers.keep_file(Shelf::Dataset, dataset.id(), &file).await.unwrap_or(false)),
            None => None,
        };
        Ok(Added { dataset, created, shared })
    }

    /// The dataset `id`: this replica's, or one another replica was sent, read from the store.
    ///
    /// # Errors
    /// When no replica has it, or it is not here and the store does not answer.
    pub async fn find(&self, id: &str) -> Result<Arc<Dataset>, DatasetError> {
        if let Some(found) = self.get(id) {
            return Ok(found);
        }
        let Some(peers) = self.peers() else {
            return Err(DatasetError::NotFound { id: id.to_owned(), shared: false });
        };
        // One read of a dataset from the store at a time: a map opening on a cold replica asks
        // for the same one many times at once, and each after the first finds it here.
        let lock = self.fetching(id);
        let _fetching = lock.lock().await;
        if let Some(found) = self.get(id) {
            return Ok(found);
        }
        // A deletion seen before is history: the store says whether it was uploaded again.
        self.undrop(id);
        let not_found = || DatasetError::NotFound { id: id.to_owned(), shared: true };
        let kept =
            peers.file(Shelf::Dataset, id).await.map_err(|_| DatasetError::Unreachable(id.to_owned()))?;
        let file = Bytes::from(kept.ok_or_else(not_found)?);
        // The file is held while it is decoded: charged like a request body.
        let _held = self.budget().charge(file.len() as u64).map_err(DatasetError::OverBudget)?;
        // Another replica took it, within its limits: no limit of this one's refuses a read.
        let (dataset, created) = self.decode(file, usize::MAX, false).await.map_err(|e| match e {
            DatasetError::OverBudget(_) => e,
            // A file some replica took, that this one cannot read: not one it serves.
            e => {
                tracing::warn!(dataset = id, error = %e, "a dataset in the store does not decode here");
                not_found()
            }
        })?;
        // Named by its hash, or not at all; and not if it was deleted while it was read.
        if dataset.id() != id || self.is_dropped(id) {
            if created {
                let _ = self.remove(dataset.id());
            }
            return Err(not_found());
        }
        tracing::info!(dataset = id, "dataset read from the store");
        Ok(dataset)
    }

    /// Deletes the uploaded dataset `id` here, in the store, and on every replica.
    ///
    /// # Errors
    /// When no replica has it, it is a file a replica's settings name, or the store does not
    /// answer.
    pub async fn delete(&self, id: &str) -> Result<(), DatasetError> {
        let here = self.remove(id);
        if here.is_ok() {
            self.drop_here(id);
        }
        let Some(peers) = self.peers() else { return here };
        match here {
            Ok(()) => {}
            Err(DatasetError::NotFound { .. }) => {
                let kept = peers.file(Shelf::Dataset, id).await;
                match kept.map_err(|_| DatasetError::Unreachable(id.to_owned()))? {
                    Some(_) => {}
                    None => return Err(DatasetError::NotFound { id: id.to_owned(), shared: true }),
                }
            }
            Err(e) => return Err(e),
        }
        peers.drop_file(Shelf::Dataset, id).await.map_err(|_| DatasetError::Unreachable(id.to_owned()))
    }

    /// The gzip of `tile` of `dataset` with `wanted`: from this replica's cache, from the
    /// store, or made now (on the blocking pool) and kept for every replica.
    ///
    /// # Errors
    /// [`DatasetError::NoTile`] when the dataset's pyramid has no such tile.
    pub async fn tile(
        &self,
        dataset: &Arc<Dataset>,
        tile: TileId,
        wanted: Wanted,
    ) -> Result<(Bytes, Made), DatasetError> {
        if let Some(gzip) = self.cached(dataset, tile, wanted) {
            return Ok((gzip, Made::Hit));
        }
        let tag = dataset.etag(tile, wanted);
        let tag = tag.trim_matches('"').to_owned();
        if let Some(peers) = self.peers()
            && let Ok(Some(gzip)) = peers.file(Shelf::Tile, &tag).await
        {
            let gzip = Bytes::from(gzip);
            self.keep(dataset, tile, wanted, gzip.clone());
            return Ok((gzip, Made::Shared));
        }
        let _permit = self.work().acquire().await.expect("the semaphore is never closed");
        let (datasets, made) = (self.clone(), dataset.clone());
        let gzip = joined(crate::cpu::spawn(move || datasets.make(&made, tile, wanted)).await)?;
        if let Some(peers) = self.peers() {
            // Kept before it is answered (a round trip beside the milliseconds it took to
            // make), so a client that asks another replica next finds it there; a store that
            // does not answer only costs the others the work.
            let _ = peers.keep_file(Shelf::Tile, &tag, &gzip).await;
        }
        Ok((gzip, Made::Miss))
    }

    /// Decodes `file` as a dataset on the blocking pool (or finds it), true when new;
    /// `allowance` counts it against the uploads' allowance.
    async fn decode(
        &self,
        file: Bytes,
        max_points: usize,
        allowance: bool,
    ) -> Result<(Arc<Dataset>, bool), DatasetError> {
        let _permit = self.work().acquire().await.expect("the semaphore is never closed");
        let datasets = self.clone();
        joined(crate::cpu::spawn(move || datasets.upload(file, max_points, allowance)).await)
    }
}

/// The outcome of work on the blocking pool; its panic goes on in the caller (a handler's
/// panic is answered as a 500 problem).
fn joined<T>(outcome: Result<T, tokio::task::JoinError>) -> T {
    outcome.unwrap_or_else(|e| std::panic::resume_unwind(e.into_panic()))
}
