//! One dataset: a DEM, where it came from, and what a client is told of it.

use super::error::DatasetError;
use crate::jobs::Charge;
use crate::tiles::{Dem, Pyramid, TileId, Wanted, max_level};
use sha2::{Digest, Sha256};
use std::path::PathBuf;

/// Where a dataset came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// `POST /v1/datasets`: its id is the hash of the file.
    Upload,
    /// A file the server's settings name (`MESHFIT_DATASET`): its id is that name.
    File(PathBuf),
}

/// A DEM that tiles are served from.
#[derive(Debug)]
pub struct Dataset {
    id: String,
    origin: Origin,
    /// SHA-256 of the file, hex: what a tile's ETag is made from, so a file replaced under
    /// the same name gives its tiles new tags.
    digest: String,
    file_bytes: u64,
    dem: Dem,
    /// Each tile within this fraction of its level's error.
    error_factor: f64,
    /// The decoded heights' share of the memory budget, held as long as the dataset.
    _charge: Charge,
}

impl Dataset {
    /// A dataset of `dem`, decoded from a file of `file_bytes` whose SHA-256 is `digest`.
    ///
    /// # Errors
    /// When its pyramid would have more tiles than a pyramid may (a wide DEM of fine pixels).
    pub(super) fn new(
        id: String,
        origin: Origin,
        digest: String,
        file_bytes: u64,
        dem: Dem,
        error_factor: f64,
        charge: Charge,
    ) -> Result<Self, DatasetError> {
        Pyramid::new(&dem, 0, Some(max_level(dem.pixel())), error_factor)?;
        Ok(Self { id, origin, digest, file_bytes, dem, error_factor, _charge: charge })
    }

    /// Its id: the hash of an uploaded file, or the name a setting gives a file.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// Where it came from.
    pub fn origin(&self) -> &Origin {
        &self.origin
    }

    /// The SHA-256 of its file, hex.
    pub fn digest(&self) -> &str {
        &self.digest
    }

    /// Its DEM.
    pub fn dem(&self) -> &Dem {
        &self.dem
    }

    /// The lowest and highest height of its data.
    pub fn heights(&self) -> [f64; 2] {
        self.dem.heights()
    }

    /// The size of its file in bytes.
    pub fn file_bytes(&self) -> u64 {
        self.file_bytes
    }

    /// The tile error's factor it is served with.
    pub fn error_factor(&self) -> f64 {
        self.error_factor
    }

    /// Its pyramid, from level 0 to where a tile's samples reach the DEM's pixel.
    pub fn pyramid(&self) -> Pyramid<'_> {
        Pyramid::new(&self.dem, 0, Some(self.max_level()), self.error_factor)
            .expect("checked when the dataset was made")
    }

    /// The deepest level.
    pub fn max_level(&self) -> u8 {
        max_level(self.dem.pixel())
    }

    /// The entity tag of `tile` with `wanted`: the same for the same bytes, on any replica,
    /// and known before the tile is made (so a revalidation costs nothing).
    pub fn etag(&self, tile: TileId, wanted: Wanted) -> String {
        let TileId { z, x, y } = tile;
        self.tag(&[
            &[z, u8::from(wanted.normals), u8::from(wanted.metadata)],
            &x.to_le_bytes(),
            &y.to_le_bytes(),
        ])
    }

    /// The entity tag of its `layer.json`.
    pub fn layer_etag(&self) -> String {
        self.tag(&[b"layer.json"])
    }

    /// The version its tiles' URLs carry: it changes whenever their bytes may (another
    /// engine, another file under the same name, another error factor).
    pub fn version(&self) -> String {
        self.tag(&[b"version"]).trim_matches('"')[..16].to_owned()
    }

    /// A strong tag of `parts` of this dataset's file, served by this engine.
    fn tag(&self, parts: &[&[u8]]) -> String {
        let mut hash = Sha256::new();
        hash.update(crate::spec::ENGINE_VERSION.as_bytes());
        hash.update(crate::tiles::TILES_VERSION.as_bytes());
        hash.update(self.digest.as_bytes());
        hash.update(self.error_factor.to_bits().to_le_bytes());
        parts.iter().for_each(|p| hash.update(p));
        format!("\"{:.32x}\"", hash.finalize())
    }
}

/// The SHA-256 of `bytes`, hex: an uploaded dataset's id.
pub fn digest(bytes: &[u8]) -> String {
    format!("{:x}", Sha256::digest(bytes))
}
