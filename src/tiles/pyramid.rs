//! A DEM's tile pyramid: which tiles exist at each level, each tile's bytes, and the
//! `layer.json` that tells a client both.

use super::dem::{Dem, DemError};
use super::mesher::{TileSurface, mesh_tile};
use super::normals::normals;
use super::quantized::{Extensions, TileMesh, encode};
use super::scheme::{MAX_LEVEL, TileId, covering, degrees_per_tile, level_error, max_level};
use super::view::View;
use crate::geom::Rect;
use serde_json::json;

/// The finest lattice a tile is meshed on, in steps a side: low levels of a large DEM would
/// otherwise sample millions of nodes for a tolerance of kilometres.
pub const MAX_STEPS: usize = 1024;

/// The coarsest: the 64 steps (65 samples) a level's error assumes.
pub const MIN_STEPS: usize = 64;

/// The most tiles a pyramid may have: a deep `max_level` over a wide DEM would otherwise list
/// trillions.
pub const MAX_TILES: u64 = 10_000_000;

/// Levels whose tiles tell, in their metadata, which tiles exist in the next this-many levels
/// of their subtree (layer.json's `metadataAvailability`, as Cesium World Terrain has it): 0,
/// 10, 20.
pub const METADATA_LEVELS: u8 = 10;

/// The extensions a tile is written with, as its client asked.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Wanted {
    /// Oct-encoded vertex normals (`octvertexnormals`).
    pub normals: bool,
    /// The availability of the tiles below (`metadata`), in tiles of levels that are
    /// multiples of [`METADATA_LEVELS`].
    pub metadata: bool,
}

impl Wanted {
    /// Every extension layer.json lists.
    pub const ALL: Wanted = Wanted { normals: true, metadata: true };
}

/// The tiles of a DEM from `min_level` to `max_level`, each within `error_factor` times its
/// level's geometric error of the DEM.
#[derive(Debug, Clone)]
pub struct Pyramid<'a> {
    dem: &'a Dem,
    min_level: u8,
    max_level: u8,
    error_factor: f64,
}

/// Why a pyramid's levels or factor are refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PyramidError {
    /// min above max, or max past the scheme's deepest level.
    #[error("levels {min}..={max} are not a range within 0..={MAX_LEVEL}")]
    Levels {
        /// The first level asked for.
        min: u8,
        /// The last.
        max: u8,
    },
    /// Not a finite factor in (0, 1].
    #[error("the error factor must be in (0, 1], got {0}")]
    Factor(f64),
    /// More tiles than [`MAX_TILES`].
    #[error(
        "levels up to {max} hold {tiles} tiles of this DEM, more than {MAX_TILES}: ask for a lower max level"
    )]
    TooMany {
        /// The last level asked for.
        max: u8,
        /// The tiles it would make.
        tiles: u64,
    },
}

impl<'a> Pyramid<'a> {
    /// The pyramid of `dem` over levels `min_level..=max_level` (the last by default where a
    /// tile's 65 samples a side first reach the DEM's pixel), each tile within `error_factor`
    /// (in (0, 1]) of its level's error.
    ///
    /// # Errors
    /// When the levels are not a range within the scheme, or the factor is out of range.
    pub fn new(
        dem: &'a Dem,
        min_level: u8,
        max: Option<u8>,
        error_factor: f64,
    ) -> Result<Self, PyramidError> {
        let max_level = max.unwrap_or_else(|| max_level(dem.pixel()));
        if min_level > max_level || max_level > MAX_LEVEL {
            return Err(PyramidError::Levels { min: min_level, max: max_level });
        }
        if !(error_factor > 0.0 && error_factor <= 1.0) {
            return Err(PyramidError::Factor(error_factor));
        }
        let pyramid = Self { dem, min_level, max_level, error_factor };
        let tiles: u64 = (0..=max_level)
            .filter_map(|z| pyramid.available(z))
            .map(|([x0, x1], [y0, y1])| u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1))
            .sum();
        if tiles > MAX_TILES {
            return Err(PyramidError::TooMany { max: max_level, tiles });
        }
        Ok(pyramid)
    }

    /// The deepest level.
    pub fn max_level(&self) -> u8 {
        self.max_level
    }

    /// The columns and rows of level `z` whose tiles the DEM's bounds meet, and at level 0
    /// both roots, as inclusive ranges. A DEM with holes may leave some of them without data:
    /// [`Pyramid::has`] says which tiles exist.
    pub fn available(&self, z: u8) -> Option<([u32; 2], [u32; 2])> {
        if z == 0 {
            return Some(([0, 1], [0, 0]));
        }
        if z < self.min_level || z > self.max_level {
            return None;
        }
        covering(&self.dem.bounds(), z)
    }

    /// Whether the pyramid has `tile`: both roots, and below them each tile within
    /// [`Pyramid::available`] that holds a sample of data (a tile wholly nodata does not
    /// exist).
    pub fn has(&self, tile: TileId) -> bool {
        let Some(([x0, x1], [y0, y1])) = self.available(tile.z) else { return false };
        (x0..=x1).contains(&tile.x)
            && (y0..=y1).contains(&tile.y)
            && (tile.z == 0 || self.dem.has_data(&tile.bounds()))
    }

    /// Every tile of the pyramid, level by level, in rows from the south.
    pub fn tiles(&self) -> Vec<TileId> {
        let levels = (0..=self.max_level).filter(|&z| z == 0 || z >= self.min_level);
        levels
            .filter_map(|z| self.available(z).map(|r| (z, r)))
            .flat_map(|(z, ([x0, x1], [y0, y1]))| {
                (y0..=y1).flat_map(move |y| (x0..=x1).map(move |x| TileId { z, x, y }))
            })
            .filter(|&tile| self.has(tile))
            .collect()
    }

    /// The tiles of level `z` within columns `x` and rows `y` that exist, as tilejson ranges:
    /// one for a DEM without holes, else the runs of each row.
    fn ranges(&self, z: u8, [x0, x1]: [u32; 2], [y0, y1]: [u32; 2]) -> serde_json::Value {
        if !self.dem.has_holes() || z == 0 {
            return json!([range([x0, x1], [y0, y1])]);
        }
        let mut runs = Vec::new();
        for y in y0..=y1 {
            let mut start = None;
            for x in x0..=x1 + 1 {
                match (start, x <= x1 && self.has(TileId { z, x, y })) {
                    (None, true) => start = Some(x),
                    (Some(s), false) => {
                        runs.push(range([s, x - 1], [y, y]));
                        start = None;
                    }
                    _ => {}
                }
            }
        }
        serde_json::Value::Array(runs)
    }

    /// The mesh of `tile`, or `None` when the pyramid has no such tile. Beyond the DEM the
    /// height is 0 (`FILL`): a root tile the DEM does not reach follows the ellipsoid.
    ///
    /// # Errors
    /// When a block of the DEM's file the tile needs cannot be read.
    pub fn surface(&self, tile: TileId) -> Result<Option<TileSurface>, DemError> {
        Ok(self.made(tile)?.map(|(surface, _)| surface))
    }

    /// The quantized-mesh-1.0 bytes of `tile` (uncompressed) with the extensions `wanted`, or
    /// `None` when the pyramid has no such tile.
    ///
    /// # Errors
    /// When a block of the DEM's file the tile needs cannot be read.
    pub fn tile(&self, tile: TileId, wanted: Wanted) -> Result<Option<Vec<u8>>, DemError> {
        let Some((surface, view)) = self.made(tile)? else { return Ok(None) };
        let normals = wanted.normals.then(|| normals(&view, &surface.vertices, self.step(tile.z)));
        let metadata =
            (wanted.metadata && tile.z.is_multiple_of(METADATA_LEVELS)).then(|| self.metadata(tile));
        let mesh =
            TileMesh { bounds: tile.bounds(), vertices: &surface.vertices, triangles: &surface.triangles };
        Ok(Some(encode(&mesh, &Extensions { normals: normals.as_deref(), metadata: metadata.as_deref() })))
    }

    /// The mesh of `tile` and the DEM's samples it was made from.
    fn made(&self, tile: TileId) -> Result<Option<(TileSurface, View<'_>)>, DemError> {
        if !self.has(tile) {
            return Ok(None);
        }
        let b = tile.bounds();
        let rect = Rect::new(b.west, b.east, b.south, b.north).expect("a tile is a proper rectangle");
        let steps = self.steps(tile.z);
        let view = self.dem.view(rect, steps, self.step(tile.z))?;
        let tolerance = level_error(tile.z) * self.error_factor;
        Ok(Some((mesh_tile(&view, tile, tolerance, steps), view)))
    }

    /// The level's lattice step in degrees, which normals are taken across: the same for
    /// every tile of the level, so neighbours give a shared vertex the same normal.
    fn step(&self, z: u8) -> f64 {
        degrees_per_tile(z) / self.steps(z) as f64
    }

    /// The metadata extension's JSON for `tile`: which tiles of its subtree exist in each of
    /// the next [`METADATA_LEVELS`] levels, the first entry for level `z + 1`.
    fn metadata(&self, tile: TileId) -> String {
        let below = (1..=METADATA_LEVELS).map(|k| {
            // Levels past the pyramid's are not available, and their columns need not fit u32.
            let Some(([ax0, ax1], [ay0, ay1])) = self.available(tile.z + k) else { return json!([]) };
            let (x0, y0) = (tile.x << k, tile.y << k);
            let (x1, y1) = (x0 + (1 << k) - 1, y0 + (1 << k) - 1);
            if ax0 <= x1 && x0 <= ax1 && ay0 <= y1 && y0 <= ay1 {
                self.ranges(tile.z + k, [x0.max(ax0), x1.min(ax1)], [y0.max(ay0), y1.min(ay1)])
            } else {
                json!([])
            }
        });
        json!({ "available": below.collect::<Vec<_>>() }).to_string()
    }

    /// Lattice steps a side at level `z`: as fine as the DEM's pixel, from [`MIN_STEPS`] to
    /// [`MAX_STEPS`].
    fn steps(&self, z: u8) -> usize {
        let pixels = (degrees_per_tile(z) / self.dem.pixel()).ceil();
        (pixels.min(MAX_STEPS as f64) as usize).next_power_of_two().clamp(MIN_STEPS, MAX_STEPS)
    }

    /// The `layer.json` of the pyramid (tilejson 2.1.0, as Cesium's terrain provider reads it):
    /// its tiles' URL template under the same directory, scheme, levels and availability,
    /// both whole (`available`, which most clients read) and level by level from the tiles'
    /// metadata (`metadataAvailability`, which CesiumJS then reads instead).
    ///
    /// The tiles' URLs carry `version` (`?v=`): a client or a CDN that keeps tiles for long
    /// never mixes those of two versions, whose neighbours would not fit.
    pub fn layer_json(&self, name: &str, version: &str) -> serde_json::Value {
        let available: Vec<_> = (0..=self.max_level)
            .map(|z| match self.available(z) {
                Some((x, y)) => self.ranges(z, x, y),
                None => json!([]),
            })
            .collect();
        let b = self.dem.bounds();
        json!({
            "tilejson": "2.1.0",
            "name": name,
            "version": version,
            "scheme": "tms",
            "tiles": ["{z}/{x}/{y}.terrain?v={version}"],
            "format": "quantized-mesh-1.0",
            "projection": "EPSG:4326",
            "bounds": [b.west, b.south, b.east, b.north],
            "minzoom": 0,
            "maxzoom": self.max_level,
            "available": available,
            "extensions": ["octvertexnormals", "metadata"],
            "metadataAvailability": METADATA_LEVELS,
            "attribution": "",
            "generator": "meshfit",
        })
    }
}

/// A range of tiles as tilejson writes it, columns and rows inclusive.
fn range([x0, x1]: [u32; 2], [y0, y1]: [u32; 2]) -> serde_json::Value {
    json!({"startX": x0, "startY": y0, "endX": x1, "endY": y1})
}
