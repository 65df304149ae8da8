//! A DEM as tiles read it: heights on a grid whose domain is longitude and latitude (WGS84,
//! EPSG:4326), with its bounds and the size of a pixel.

use super::scheme::Bounds;
use crate::source::{Crs, DecodedGrid, Grid};

/// A DEM on longitude and latitude.
#[derive(Debug, Clone)]
pub struct Dem {
    grid: Grid,
    bounds: Bounds,
    /// With holes (nodata samples, filled): the data samples in [0, i) × [0, j), at
    /// `j·(nx + 1) + i`, so that whether a tile holds data is four reads.
    data: Option<Vec<u32>>,
    filled: u64,
}

/// Why a grid cannot be tiled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DemError {
    /// No georeferencing tags: nothing places the samples on the Earth.
    #[error(
        "the file is not georeferenced: terrain tiles need a GeoTIFF with ModelPixelScale and ModelTiepoint (or ModelTransformation) in EPSG:4326"
    )]
    NotGeoreferenced,
    /// Georeferenced, but its keys name no coordinate system.
    #[error("the GeoTIFF names no coordinate system (no GeoKeyDirectory): terrain tiles need EPSG:4326")]
    NoSystem,
    /// A projected system, which this version does not reproject.
    #[error(
        "the GeoTIFF is in {}, a projected system; terrain tiles need longitude and latitude: reproject it to EPSG:4326 first (gdalwarp -t_srs EPSG:4326)",
        epsg(*.0)
    )]
    Projected(Option<u16>),
    /// Longitude and latitude on another datum than WGS84.
    #[error("the GeoTIFF is in {}, not WGS84 (EPSG:4326): reproject it first (gdalwarp -t_srs EPSG:4326)", epsg(*.0))]
    OtherDatum(Option<u16>),
    /// Degrees outside the globe.
    #[error("the bounds [{west}, {east}] × [{south}, {north}] are not longitude and latitude in degrees")]
    OffTheGlobe {
        /// West bound.
        west: f64,
        /// East bound.
        east: f64,
        /// South bound.
        south: f64,
        /// North bound.
        north: f64,
    },
}

fn epsg(code: Option<u16>) -> String {
    code.map_or_else(|| "a user-defined system".to_owned(), |c| format!("EPSG:{c}"))
}

/// The EPSG code of WGS84's longitude and latitude.
pub const WGS84: u16 = 4326;

impl Dem {
    /// The DEM of a decoded GeoTIFF in EPSG:4326.
    ///
    /// # Errors
    /// When the file is not georeferenced, names another system than EPSG:4326, or its
    /// bounds are not degrees on the globe.
    pub fn new(decoded: DecodedGrid) -> Result<Self, DemError> {
        let domain = decoded.domain.ok_or(DemError::NotGeoreferenced)?;
        match decoded.crs {
            Some(Crs::Geographic(Some(WGS84))) => {}
            None => return Err(DemError::NoSystem),
            Some(Crs::Projected(code)) => return Err(DemError::Projected(code)),
            Some(Crs::Geographic(code)) => return Err(DemError::OtherDatum(code)),
        }
        let bounds = Bounds { west: domain.x0(), south: domain.y0(), east: domain.x1(), north: domain.y1() };
        // A nanodegree of slack: a global DEM's pixel centres may land a rounding past ±180.
        let off = |v: f64, limit: f64| v.abs() > limit + 1e-9;
        if off(bounds.west, 180.0)
            || off(bounds.east, 180.0)
            || off(bounds.south, 90.0)
            || off(bounds.north, 90.0)
        {
            let Bounds { west, south, east, north } = bounds;
            return Err(DemError::OffTheGlobe { west, east, south, north });
        }
        let (nx, ny) = (decoded.grid.nx(), decoded.grid.ny());
        let filled = decoded.holes.as_ref().map_or(0, |h| h.iter().filter(|&&h| h).count() as u64);
        let data = decoded.holes.map(|holes| {
            let mut counts = vec![0u32; (nx + 1) * (ny + 1)];
            for j in 0..ny {
                let mut row = 0;
                for i in 0..nx {
                    row += u32::from(!holes[j * nx + i]);
                    counts[(j + 1) * (nx + 1) + i + 1] = counts[j * (nx + 1) + i + 1] + row;
                }
            }
            counts
        });
        Ok(Self { grid: decoded.grid.with_domain(domain), bounds, data, filled })
    }

    /// How many samples were nodata, filled from their neighbours.
    pub fn filled(&self) -> u64 {
        self.filled
    }

    /// Whether the DEM has holes (nodata samples, filled for meshing).
    pub fn has_holes(&self) -> bool {
        self.data.is_some()
    }

    /// Whether a sample of data (not a filled hole) lies in `bounds` (sides included); for a
    /// DEM without holes, whether its bounds meet them.
    pub fn has_data(&self, bounds: &Bounds) -> bool {
        let b = self.bounds;
        let meets = bounds.west <= b.east
            && b.west <= bounds.east
            && bounds.south <= b.north
            && b.south <= bounds.north;
        let Some(counts) = &self.data else { return meets };
        if !meets {
            return false;
        }
        let (nx, ny) = (self.grid.nx(), self.grid.ny());
        let (u0, v0) = self.grid.to_grid(crate::geom::Point::new(bounds.west, bounds.south));
        let (u1, v1) = self.grid.to_grid(crate::geom::Point::new(bounds.east, bounds.north));
        // The samples inside: columns ceil(u0)..=floor(u1), rows likewise.
        let first = |u: f64| u.ceil().max(0.0) as usize;
        let last = |u: f64, n: usize| (u.floor().max(-1.0) + 1.0).min(n as f64) as usize;
        let (i0, i1, j0, j1) = (first(u0), last(u1, nx), first(v0), last(v1, ny));
        if i0 >= i1 || j0 >= j1 {
            return false;
        }
        let at = |i: usize, j: usize| i64::from(counts[j * (nx + 1) + i]);
        at(i1, j1) - at(i0, j1) - at(i1, j0) + at(i0, j0) > 0
    }

    /// The heights, on longitude (x) and latitude (y).
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// The bounds of the samples, in degrees.
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }

    /// The finer of the two sample spacings, in degrees.
    pub fn pixel(&self) -> f64 {
        let b = self.bounds;
        let dx = (b.east - b.west) / (self.grid.nx() - 1) as f64;
        let dy = (b.north - b.south) / (self.grid.ny() - 1) as f64;
        dx.min(dy)
    }
}
