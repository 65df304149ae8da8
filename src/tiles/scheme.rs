//! The tiling scheme web-map terrain clients use: geographic (EPSG:4326) tiles in TMS order,
//! two at level 0 (west and east of the antimeridian's opposite), each split in four below.
//!
//! Tile (z, x, y) spans 180/2^z degrees of longitude and of latitude, x counting from −180°
//! eastward and y from −90° northward (TMS: y grows north). Every bound is a multiple of a
//! power of two of a degree, so it is exact in f64 down to level 40 and neighbours share
//! their edges bit for bit.

/// A tile of the geographic scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileId {
    /// The level; 0 has two tiles.
    pub z: u8,
    /// Column, from the antimeridian eastward: 0 .. 2^(z+1).
    pub x: u32,
    /// Row, from the south pole northward: 0 .. 2^z.
    pub y: u32,
}

/// The deepest level served: 2^(z+1) columns must fit a u32, and a tile there is a few
/// millimetres wide.
pub const MAX_LEVEL: u8 = 30;

/// Samples a side a level's error assumes (Cesium's heightmap tiles are 65 × 65).
pub const TILE_SAMPLES: u32 = 65;

/// The geometric error of level 0, in metres: the equatorial circumference over the two
/// level-0 tiles of [`TILE_SAMPLES`] samples a side, a quarter of it (Cesium's
/// `getEstimatedLevelZeroGeometricErrorForAHeightmap`). Clients refine a tile when this
/// error, halved at each level, looks larger than their screen-space limit.
pub const LEVEL_ZERO_ERROR: f64 =
    super::ellipsoid::SEMI_MAJOR_AXIS * 2.0 * std::f64::consts::PI * 0.25 / (TILE_SAMPLES as f64 * 2.0);

/// A tile's bounds in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Western longitude.
    pub west: f64,
    /// Southern latitude.
    pub south: f64,
    /// Eastern longitude.
    pub east: f64,
    /// Northern latitude.
    pub north: f64,
}

impl Bounds {
    /// Longitude and latitude of the centre.
    pub fn centre(&self) -> (f64, f64) {
        (self.west / 2.0 + self.east / 2.0, self.south / 2.0 + self.north / 2.0)
    }

    /// Whether the two boxes share some area (touching edges do not count).
    pub fn overlaps(&self, other: &Bounds) -> bool {
        self.west < other.east
            && other.west < self.east
            && self.south < other.north
            && other.south < self.north
    }
}

/// Why a tile address is not one of the scheme's.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TileError {
    /// Past [`MAX_LEVEL`].
    #[error("level {z} is past the deepest level, {MAX_LEVEL}")]
    Level {
        /// The level asked for.
        z: u32,
    },
    /// x or y outside the level.
    #[error("tile {x}/{y} is outside level {z}, which has x in 0..{columns} and y in 0..{rows}")]
    Outside {
        /// The level.
        z: u8,
        /// The column asked for.
        x: u32,
        /// The row asked for.
        y: u32,
        /// Columns at the level.
        columns: u32,
        /// Rows at the level.
        rows: u32,
    },
}

impl TileId {
    /// Tile (z, x, y), if the scheme has it.
    ///
    /// # Errors
    /// When z is past [`MAX_LEVEL`] or x, y are outside the level.
    pub fn new(z: u32, x: u32, y: u32) -> Result<Self, TileError> {
        let z = u8::try_from(z).ok().filter(|&z| z <= MAX_LEVEL).ok_or(TileError::Level { z })?;
        let (columns, rows) = (columns(z), rows(z));
        if x >= columns || y >= rows {
            return Err(TileError::Outside { z, x, y, columns, rows });
        }
        Ok(Self { z, x, y })
    }

    /// The tile's bounds in degrees.
    pub fn bounds(&self) -> Bounds {
        let size = degrees_per_tile(self.z);
        let (west, south) = (-180.0 + f64::from(self.x) * size, -90.0 + f64::from(self.y) * size);
        Bounds { west, south, east: west + size, north: south + size }
    }

    /// The four tiles of the next level that cover this one, south-west first, then
    /// south-east, north-west, north-east.
    ///
    /// # Panics
    /// At [`MAX_LEVEL`], which has no level below.
    pub fn children(&self) -> [TileId; 4] {
        assert!(self.z < MAX_LEVEL, "level {MAX_LEVEL} has no children");
        let (z, x, y) = (self.z + 1, 2 * self.x, 2 * self.y);
        [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)].map(|(x, y)| TileId { z, x, y })
    }

    /// The tile of the level above that covers this one.
    pub fn parent(&self) -> Option<TileId> {
        (self.z > 0).then(|| TileId { z: self.z - 1, x: self.x / 2, y: self.y / 2 })
    }

    /// The geometric error of the tile's level, in metres.
    pub fn error(&self) -> f64 {
        level_error(self.z)
    }
}

/// Columns at level `z`: 2^(z+1).
pub fn columns(z: u8) -> u32 {
    2u32 << z
}

/// Rows at level `z`: 2^z.
pub fn rows(z: u8) -> u32 {
    1u32 << z
}

/// Degrees a tile of level `z` spans, in longitude and in latitude: 180 / 2^z, exact.
pub fn degrees_per_tile(z: u8) -> f64 {
    180.0 / f64::from(rows(z))
}

/// The geometric error of level `z`, in metres: [`LEVEL_ZERO_ERROR`] / 2^z.
pub fn level_error(z: u8) -> f64 {
    LEVEL_ZERO_ERROR / f64::from(rows(z))
}

/// The first level whose tiles, at [`TILE_SAMPLES`] samples a side, sample at least as finely
/// as `pixel_degrees` (a DEM's pixel size): past it a tile would only interpolate the DEM.
pub fn max_level(pixel_degrees: f64) -> u8 {
    (0..MAX_LEVEL)
        .find(|&z| degrees_per_tile(z) / f64::from(TILE_SAMPLES - 1) <= pixel_degrees)
        .unwrap_or(MAX_LEVEL)
}

/// The tiles of level `z` that `area` overlaps, as inclusive column and row ranges, or
/// `None` when it overlaps none.
pub fn covering(area: &Bounds, z: u8) -> Option<([u32; 2], [u32; 2])> {
    let size = degrees_per_tile(z);
    let (columns, rows) = (columns(z), rows(z));
    // The last tile whose west (south) edge lies strictly before the area's east (north)
    // edge: an area ending exactly on a tile edge does not reach into the next tile.
    let first =
        |lo: f64, origin: f64, count: u32| (((lo - origin) / size).floor().max(0.0) as u32).min(count - 1);
    let last = |hi: f64, origin: f64, count: u32| {
        let k = ((hi - origin) / size).ceil() as i64 - 1;
        k.clamp(0, i64::from(count) - 1) as u32
    };
    let x = [first(area.west, -180.0, columns), last(area.east, -180.0, columns)];
    let y = [first(area.south, -90.0, rows), last(area.north, -90.0, rows)];
    let whole = Bounds { west: -180.0, south: -90.0, east: 180.0, north: 90.0 };
    (area.overlaps(&whole) && x[0] <= x[1] && y[0] <= y[1]).then_some((x, y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn level_zero_is_two_tiles_split_at_the_prime_meridian() {
        let west = TileId::new(0, 0, 0).unwrap().bounds();
        let east = TileId::new(0, 1, 0).unwrap().bounds();
        assert_eq!(west, Bounds { west: -180.0, south: -90.0, east: 0.0, north: 90.0 });
        assert_eq!(east, Bounds { west: 0.0, south: -90.0, east: 180.0, north: 90.0 });
        assert!(matches!(TileId::new(0, 2, 0), Err(TileError::Outside { columns: 2, rows: 1, .. })));
        assert!(matches!(TileId::new(31, 0, 0), Err(TileError::Level { z: 31 })));
        assert!(matches!(TileId::new(300, 0, 0), Err(TileError::Level { z: 300 })));
    }

    #[test]
    fn the_level_error_is_cesiums() {
        // Cesium's figure for a geographic scheme of two root tiles and 65-sample tiles.
        assert!((LEVEL_ZERO_ERROR - 77_067.34).abs() < 0.01, "{LEVEL_ZERO_ERROR}");
        assert_eq!(level_error(3), LEVEL_ZERO_ERROR / 8.0);
    }

    #[test]
    fn the_max_level_samples_a_pixel_at_least() {
        // One arc-second (SRTM): 180/2^z/64 ≤ 1/3600 first at z = 14 (0.000172° a sample).
        let z = max_level(1.0 / 3600.0);
        assert_eq!(z, 14);
        assert!(degrees_per_tile(z) / 64.0 <= 1.0 / 3600.0 && degrees_per_tile(z - 1) / 64.0 > 1.0 / 3600.0);
    }

    #[test]
    fn covering_names_exactly_the_tiles_an_area_overlaps() {
        // Level 2: tiles of 45°. An area from 10°E to 45°E ends on a tile edge.
        let area = Bounds { west: 10.0, south: 40.0, east: 45.0, north: 50.0 };
        assert_eq!(covering(&area, 2), Some(([4, 4], [2, 3])));
        let outside = Bounds { west: 190.0, south: 0.0, east: 200.0, north: 1.0 };
        assert_eq!(covering(&outside, 2), None);
    }

    proptest! {
        /// Children tile their parent exactly, and neighbours share edges bit for bit.
        #[test]
        fn children_tile_their_parent_and_neighbours_share_edges(z in 0u8..MAX_LEVEL, fx in 0.0f64..1.0, fy in 0.0f64..1.0) {
            let x = ((f64::from(columns(z)) * fx) as u32).min(columns(z) - 1);
            let y = ((f64::from(rows(z)) * fy) as u32).min(rows(z) - 1);
            let tile = TileId::new(u32::from(z), x, y).unwrap();
            let b = tile.bounds();
            let [sw, se, nw, ne] = tile.children().map(|c| c.bounds());
            prop_assert_eq!((sw.west, sw.south, ne.east, ne.north), (b.west, b.south, b.east, b.north));
            prop_assert_eq!((sw.east, sw.north), (se.west, nw.south));
            prop_assert_eq!((ne.west, ne.south), (nw.east, se.north));
            for child in tile.children() {
                prop_assert_eq!(child.parent(), Some(tile));
            }
            if x + 1 < columns(z) {
                let right = TileId::new(u32::from(z), x + 1, y).unwrap().bounds();
                prop_assert_eq!(right.west, b.east);
            }
            prop_assert_eq!(covering(&b, z), Some(([x, x], [y, y])));
        }
    }
}
