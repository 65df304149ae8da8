//! A DEM's tile pyramid: which tiles exist at each level, each tile's bytes, and the
//! `layer.json` that tells a client both.

use super::dem::Dem;
use super::mesher::{TileSurface, mesh_tile};
use super::normals::normals;
use super::quantized::{Extensions, TileMesh, encode};
use super::scheme::{MAX_LEVEL, TileId, covering, degrees_per_tile, level_error, max_level};
use serde_json::json;

/// The finest lattice a tile is meshed on, in steps a side: low levels of a large DEM would
/// otherwise sample millions of nodes for a tolerance of kilometres.
pub const MAX_STEPS: usize = 1024;

/// The coarsest: the 64 steps (65 samples) a level's error assumes.
pub const MIN_STEPS: usize = 64;

/// The most tiles a pyramid may have: a deep `max_level` over a wide DEM would otherwise list
/// trillions.
pub const MAX_TILES: u64 = 10_000_000;

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

    /// The tiles of level `z` that exist: those the DEM overlaps, and at level 0 both roots
    /// (a client always asks for them), as inclusive column and row ranges.
    pub fn available(&self, z: u8) -> Option<([u32; 2], [u32; 2])> {
        if z == 0 {
            return Some(([0, 1], [0, 0]));
        }
        if z < self.min_level || z > self.max_level {
            return None;
        }
        covering(&self.dem.bounds(), z)
    }

    /// Every tile of the pyramid, level by level, in rows from the south.
    pub fn tiles(&self) -> Vec<TileId> {
        let levels = (0..=self.max_level).filter(|&z| z == 0 || z >= self.min_level);
        levels
            .filter_map(|z| self.available(z).map(|r| (z, r)))
            .flat_map(|(z, ([x0, x1], [y0, y1]))| {
                (y0..=y1).flat_map(move |y| (x0..=x1).map(move |x| TileId { z, x, y }))
            })
            .collect()
    }

    /// The mesh of `tile`, or `None` when the pyramid has no such tile. Beyond the DEM the
    /// height is 0 (`FILL`): a root tile the DEM does not reach follows the ellipsoid.
    pub fn surface(&self, tile: TileId) -> Option<TileSurface> {
        let ([x0, x1], [y0, y1]) = self.available(tile.z)?;
        if !(x0..=x1).contains(&tile.x) || !(y0..=y1).contains(&tile.y) {
            return None;
        }
        let tolerance = level_error(tile.z) * self.error_factor;
        Some(mesh_tile(self.dem.grid(), tile, tolerance, self.steps(tile.z)))
    }

    /// The quantized-mesh-1.0 bytes of `tile` (uncompressed) with its vertex normals
    /// (`octvertexnormals`), or `None` when the pyramid has no such tile.
    pub fn tile(&self, tile: TileId) -> Option<Vec<u8>> {
        let surface = self.surface(tile)?;
        // The level's lattice step: the same for every tile of the level, so neighbours give
        // a shared vertex the same normal.
        let step = degrees_per_tile(tile.z) / self.steps(tile.z) as f64;
        let normals = normals(self.dem.grid(), &surface.vertices, step);
        let mesh =
            TileMesh { bounds: tile.bounds(), vertices: &surface.vertices, triangles: &surface.triangles };
        Some(encode(&mesh, &Extensions { normals: Some(&normals), metadata: None }))
    }

    /// Lattice steps a side at level `z`: as fine as the DEM's pixel, from [`MIN_STEPS`] to
    /// [`MAX_STEPS`].
    fn steps(&self, z: u8) -> usize {
        let pixels = (degrees_per_tile(z) / self.dem.pixel()).ceil();
        (pixels.min(MAX_STEPS as f64) as usize).next_power_of_two().clamp(MIN_STEPS, MAX_STEPS)
    }

    /// The `layer.json` of the pyramid (tilejson 2.1.0, as Cesium's terrain provider reads it):
    /// its tiles' URL template under the same directory, scheme, levels and availability.
    pub fn layer_json(&self, name: &str) -> serde_json::Value {
        let available: Vec<_> = (0..=self.max_level)
            .map(|z| match self.available(z) {
                Some(([x0, x1], [y0, y1])) => json!([{"startX": x0, "startY": y0, "endX": x1, "endY": y1}]),
                None => json!([]),
            })
            .collect();
        let b = self.dem.bounds();
        json!({
            "tilejson": "2.1.0",
            "name": name,
            "version": "1.0.0",
            "scheme": "tms",
            "tiles": ["{z}/{x}/{y}.terrain"],
            "format": "quantized-mesh-1.0",
            "projection": "EPSG:4326",
            "bounds": [b.west, b.south, b.east, b.north],
            "minzoom": 0,
            "maxzoom": self.max_level,
            "available": available,
            "extensions": ["octvertexnormals"],
            "attribution": "",
            "generator": "meshfit",
        })
    }
}
