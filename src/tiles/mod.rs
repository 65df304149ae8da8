//! Terrain tiles for web maps: the geographic tiling scheme that terrain clients (CesiumJS,
//! cesium-native, 3DTilesRendererJS, loaders.gl) stream by z/x/y, the WGS84 geometry of a
//! tile's header, and the quantized-mesh-1.0 format they read.
//!
//! - `scheme`: [`TileId`], a tile's bounds in degrees, its children and parent, each level's
//!   geometric error, and the deepest level a DEM's resolution calls for;
//! - `dem`: a DEM on longitude and latitude (a GeoTIFF in EPSG:4326) read block by block, or
//!   why a file is not;
//! - `view`: the samples of a DEM one tile reads, placed in the whole DEM's frame;
//! - `pyramid`: the tiles a DEM has at each level, each tile's bytes, and `layer.json`;
//! - `ellipsoid`: ECEF positions, a bounding sphere and the horizon occlusion point;
//! - `mesher`: a tile's mesh from a DEM within a tolerance, its sides fixed from their own
//!   values so that neighbours share their vertices;
//! - `normals`: per-vertex normals from the DEM around each vertex (octvertexnormals);
//! - `quantized`: a tile's mesh as quantized-mesh-1.0, with the octvertexnormals and
//!   metadata extensions.

/// The version of the tiles' meshing, beside the engine's (`ENGINE_VERSION`): a tile's bytes
/// are the same for the same DEM, level and factor within both, and its entity tag names
/// both. Bumped when a better rule changes tiles.
pub const TILES_VERSION: &str = "meshfit-tiles-3";

mod dem;
mod ellipsoid;
mod mesher;
mod normals;
mod pyramid;
mod quantized;
mod scheme;
mod view;

pub use dem::{BLOCK_CACHE_BYTES, Dem, DemError, WGS84};
pub use ellipsoid::{SEMI_MAJOR_AXIS, SEMI_MINOR_AXIS, to_ecef};
pub use mesher::{TileSurface, mesh_tile, simplify};
pub use normals::normals;
pub use pyramid::{MAX_STEPS, MAX_TILES, METADATA_LEVELS, MIN_STEPS, Pyramid, PyramidError, Wanted};
pub use quantized::{Extensions, QUANTIZED_MAX, TileMesh, encode};
pub use scheme::{
    Bounds, LEVEL_ZERO_ERROR, MAX_LEVEL, TILE_SAMPLES, TileError, TileId, columns, covering,
    degrees_per_tile, level_error, max_level, rows,
};
pub use view::{MAX_SAMPLES, View};
