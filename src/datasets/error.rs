//! Why a dataset or a tile cannot be had.

use crate::jobs::OverBudget;
use crate::source::GridFileError;
use crate::tiles::{DemError, PyramidError};

/// Why a dataset cannot be added, found or removed, or a tile made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DatasetError {
    /// The file is not a grid file that decodes.
    #[error("the DEM file: {0}")]
    File(#[from] GridFileError),
    /// A grid, but not a DEM that tiles can be made of.
    #[error("{0}")]
    Dem(#[from] DemError),
    /// A DEM whose pyramid would have too many tiles.
    #[error("{0}")]
    Pyramid(#[from] PyramidError),
    /// No dataset has this id (on any replica, when `shared`).
    #[error(
        "no dataset `{id}`{}; upload a GeoTIFF with POST /v1/datasets (curl -F grid=@dem.tif)",
        if *shared { " on any replica (an upload larger than MESHFIT_REDIS_MAX_BYTES stays on the replica it was sent to)" } else { "" }
    )]
    NotFound {
        /// The id asked for.
        id: String,
        /// Whether replicas share datasets through a store, which was asked too.
        shared: bool,
    },
    /// The dataset is not here, and the store replicas share does not answer.
    #[error(
        "dataset `{0}` is not known here, and Redis, through which replicas share datasets, does not answer"
    )]
    Unreachable(String),
    /// The dataset has no such tile.
    #[error("{0}")]
    NoTile(String),
    /// A dataset the settings name cannot be deleted through the API.
    #[error("dataset `{0}` is a file named in this server's settings (MESHFIT_DATASET); it is removed there")]
    Configured(String),
    /// Uploaded datasets would hold more than `MESHFIT_DATASET_BYTES`.
    #[error(
        "this DEM takes {needed} bytes (its file and a cache of its blocks) and uploaded datasets may hold {limit} (MESHFIT_DATASET_BYTES), of which {held} are held: delete a dataset first"
    )]
    Full {
        /// Bytes the DEM takes: its file and its blocks' cache.
        needed: u64,
        /// Bytes uploaded datasets hold now.
        held: u64,
        /// The limit.
        limit: u64,
    },
    /// A block of the dataset's file cannot be read now (a file changed or gone on disk).
    #[error("dataset `{id}`: {detail}")]
    Unreadable {
        /// The dataset.
        id: String,
        /// What the reader said.
        detail: String,
    },
    /// The memory budget has no room for the DEM, or a tile.
    #[error("the memory budget has {} bytes free, and {} are needed", .0.available, .0.needed)]
    OverBudget(OverBudget),
}
