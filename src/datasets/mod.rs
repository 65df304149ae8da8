//! The DEMs this server makes terrain tiles of: uploaded ones (their id the hash of the file)
//! and files its settings name, each held decoded and charged to the memory budget, and the
//! tiles made of them, gzipped, in a cache under the same budget.
//!
//! - `registry`: [`Datasets`], the datasets by id, adding, finding and removing them, and the
//!   tile cache; [`DatasetSettings`];
//! - `dataset`: one [`Dataset`], its DEM, origin and pyramid, and its tiles' entity tags;
//! - `shared`: the datasets as a client of any replica sees them: uploads and tiles kept in
//!   the store replicas share, deletions told to every replica ([`Added`], [`Made`]);
//! - `error`: [`DatasetError`], why a dataset or a tile cannot be had.

mod dataset;
mod error;
mod registry;
mod shared;

pub use dataset::{Dataset, Origin, digest};
pub use error::DatasetError;
pub use registry::{DatasetSettings, Datasets};
pub use shared::{Added, Made};
