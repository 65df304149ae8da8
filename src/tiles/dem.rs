//! A DEM as tiles read it: heights on a grid whose domain is longitude and latitude (WGS84,
//! EPSG:4326), read from its GeoTIFF block by block, so that a file larger than memory serves
//! tiles reading only the blocks each needs.
//!
//! Opening a DEM reads every block once, for what a tile must know before it reads any: the
//! height range, and which blocks hold data (and, in a block that holds some, which samples),
//! so whether a tile exists costs no read. Then blocks are read as tiles need them and kept
//! in a cache of [`BLOCK_CACHE_BYTES`].

use super::mesher::clearance;
use super::scheme::Bounds;
use super::view::{Frame, MAX_SAMPLES, View, count};
use crate::geom::Rect;
use crate::source::{
    Block, BlockReader, Crs, GridFileError, GridFileKind, TiffBlocks, fill_holes, node_coordinate,
    signed_kind,
};
use std::collections::HashMap;
use std::io::{Read, Seek, SeekFrom};
use std::sync::Arc;

/// The memory each DEM keeps its latest blocks in, decoded (or one block, when a block is
/// larger).
pub const BLOCK_CACHE_BYTES: u64 = 64 << 20;

/// A DEM on longitude and latitude.
pub struct Dem {
    file: TiffBlocks,
    frame: Frame,
    bounds: Bounds,
    heights: [f64; 2],
    filled: u64,
    /// Samples of data (not nodata) in each block, blocks row by row from the top left.
    data: Vec<u32>,
    /// For each block that holds both data and nodata, which samples are nodata, a bit each
    /// in the block's order.
    holes: HashMap<usize, Vec<u64>>,
    /// Each block's mean height of data; for a block wholly nodata, the height it is filled
    /// with.
    means: Vec<f64>,
    cache: moka::sync::Cache<usize, Arc<Block>>,
}

impl std::fmt::Debug for Dem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Dem").field("file", &self.file).field("bounds", &self.bounds).finish_non_exhaustive()
    }
}

/// Why a grid cannot be tiled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DemError {
    /// The file is not a GeoTIFF meshfit reads, or a block of it does not decode.
    #[error(transparent)]
    File(#[from] GridFileError),
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
    /// Opens the GeoTIFF `reader` holds, of at most `max_points` samples, and reads each of
    /// its blocks once (see the module's docs).
    ///
    /// # Errors
    /// When the file is not a GeoTIFF meshfit reads, is not georeferenced, names another
    /// system than EPSG:4326, its bounds are not degrees on the globe, a block does not
    /// decode, or every sample is nodata.
    pub fn open(mut reader: Box<dyn BlockReader>, max_points: usize) -> Result<Self, DemError> {
        // Another grid format decodes, but nothing in it places its samples on the Earth.
        let mut signature = Vec::with_capacity(8);
        let io =
            |e: std::io::Error| GridFileError::Corrupt { kind: GridFileKind::Tiff, detail: e.to_string() };
        (&mut reader).take(8).read_to_end(&mut signature).map_err(io)?;
        if signed_kind(&signature) != Some(GridFileKind::Tiff) {
            return Err(DemError::NotGeoreferenced);
        }
        reader.seek(SeekFrom::Start(0)).map_err(io)?;
        let file = TiffBlocks::open(reader, max_points)?;
        let domain = file.domain().ok_or(DemError::NotGeoreferenced)?;
        match file.crs() {
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
        let [nx, ny] = file.size();
        let frame = Frame { nx, ny, rect: domain };
        let [across, down] = file.blocks();
        let (mut data, mut holes, mut means) =
            (Vec::with_capacity(across * down), HashMap::new(), Vec::with_capacity(across * down));
        let (mut heights, mut filled) = ([f64::INFINITY, f64::NEG_INFINITY], 0);
        for by in 0..down {
            for bx in 0..across {
                let block = file.read([bx, by], f64::NAN)?;
                let mask = block.holes.as_deref();
                let is_data = |k: usize| mask.is_none_or(|m| !m[k]);
                let (mut known, mut sum) = (0usize, 0.0);
                for (k, &v) in block.values.iter().enumerate() {
                    if is_data(k) {
                        heights = [heights[0].min(v), heights[1].max(v)];
                        (known, sum) = (known + 1, sum + v);
                    }
                }
                filled += (block.values.len() - known) as u64;
                if let Some(mask) = mask.filter(|_| known > 0) {
                    let mut bits = vec![0u64; mask.len().div_ceil(64)];
                    mask.iter()
                        .enumerate()
                        .filter(|(_, h)| **h)
                        .for_each(|(k, _)| bits[k / 64] |= 1 << (k % 64));
                    holes.insert(by * across + bx, bits);
                }
                data.push(u32::try_from(known).expect("a block of fewer than 2^32 samples"));
                means.push(if known > 0 { sum / known as f64 } else { f64::NAN });
            }
        }
        if heights[0] > heights[1] {
            return Err(GridFileError::AllNoData(file.nodata().unwrap_or(f64::NAN)).into());
        }
        // A block wholly nodata is level at the mean of the blocks of data nearest it, layer
        // by layer over the blocks: a function of the file alone, as a block's own fill is.
        fill_holes(&mut means, [across, down], f64::is_nan).expect("a block holds data");
        // At least one block, however large (a file in one strip): a tile then decodes it
        // once, not for every tile.
        let decoded = (nx as u64).saturating_mul(ny as u64).saturating_mul(8);
        let [bw, bh] = file.block_size();
        let block = (bw as u64).saturating_mul(bh as u64).saturating_mul(8);
        let cache = moka::sync::Cache::builder()
            .max_capacity(decoded.min(BLOCK_CACHE_BYTES.max(block)))
            .weigher(|_: &usize, b: &Arc<Block>| u32::try_from(b.values.len() * 8).unwrap_or(u32::MAX))
            .build();
        Ok(Self { file, frame, bounds, heights, filled, data, holes, means, cache })
    }

    /// How many samples were nodata, filled from their neighbours.
    pub fn filled(&self) -> u64 {
        self.filled
    }

    /// Whether the DEM has holes (nodata samples, filled for meshing).
    pub fn has_holes(&self) -> bool {
        self.filled > 0
    }

    /// The lowest and highest height of its data.
    pub fn heights(&self) -> [f64; 2] {
        self.heights
    }

    /// Columns and rows.
    pub fn size(&self) -> [usize; 2] {
        [self.frame.nx, self.frame.ny]
    }

    /// The memory it keeps: its blocks' cache, and which samples of each block are data.
    pub fn resident_bytes(&self) -> u64 {
        let masks: usize = self.holes.values().map(|bits| bits.len() * 8).sum();
        self.cache.policy().max_capacity().unwrap_or(0) + (self.data.len() * 12 + masks) as u64
    }

    /// Whether a sample of data (not a filled hole) lies in `bounds` (sides included).
    pub fn has_data(&self, bounds: &Bounds) -> bool {
        let b = self.bounds;
        if !(bounds.west <= b.east
            && b.west <= bounds.east
            && bounds.south <= b.north
            && b.south <= bounds.north)
        {
            return false;
        }
        if !self.has_holes() {
            return true;
        }
        let (nx, ny, frame) = (self.frame.nx, self.frame.ny, &self.frame);
        let (u, v) = (|x| frame.u(x), |y| frame.v(y));
        // The samples inside: columns ceil(u0)..=floor(u1), rows likewise, a sample within a
        // rounding of a side counted in (as the side is).
        const SLACK: f64 = 1e-9;
        let first = |u: f64| (u - SLACK).ceil().max(0.0) as usize;
        let last = |u: f64, n: usize| ((u + SLACK).floor().max(-1.0) + 1.0).min(n as f64) as usize;
        let (i0, i1) = (first(u(bounds.west)), last(u(bounds.east), nx));
        let (j0, j1) = (first(v(bounds.south)), last(v(bounds.north), ny));
        if i0 >= i1 || j0 >= j1 {
            return false;
        }
        // Image rows run down from the north.
        let (r0, r1) = (ny - j1, ny - j0);
        let [bw, bh] = self.file.block_size();
        let across = self.file.blocks()[0];
        (r0 / bh..=(r1 - 1) / bh).any(|by| {
            (i0 / bw..=(i1 - 1) / bw).any(|bx| {
                let index = by * across + bx;
                match (self.data[index], self.holes.get(&index)) {
                    (0, _) => false,
                    (_, None) => true,
                    (_, Some(bits)) => {
                        let width = bw.min(nx - bx * bw);
                        let rows = r0.max(by * bh)..r1.min((by + 1) * bh);
                        rows.flat_map(|r| (i0.max(bx * bw)..i1.min((bx + 1) * bw)).map(move |i| (r, i))).any(
                            |(r, i)| {
                                let k = (r - by * bh) * width + (i - bx * bw);
                                bits[k / 64] & (1 << (k % 64)) == 0
                            },
                        )
                    }
                }
            })
        })
    }

    /// The samples a tile over `rect`, meshed on a lattice of `steps` a side with normals
    /// from heights `step` degrees either side of each vertex, reads: a window around it, or
    /// for a tile over more than [`MAX_SAMPLES`] of the DEM's samples, only those its lattice
    /// and normals interpolate.
    ///
    /// # Errors
    /// When a block it needs cannot be read.
    pub fn view(&self, rect: Rect, steps: usize, step: f64) -> Result<View<'_>, DemError> {
        self.view_within(rect, steps, step, MAX_SAMPLES)
    }

    /// [`Dem::view`], reading a window of at most `max_window` samples.
    fn view_within(
        &self,
        rect: Rect,
        steps: usize,
        step: f64,
        max_window: usize,
    ) -> Result<View<'_>, DemError> {
        let frame = &self.frame;
        match frame.inside(rect, clearance(rect, steps)) {
            Some(inside @ [i0, i1, j0, j1]) if count(inside) <= max_window => {
                // The lattice's extreme positions, a step beyond its sides, bound what the
                // lattice and its normals read (a cell's columns grow with x).
                let (west, east) = (frame.columns_at(rect.x0() - step), frame.columns_at(rect.x1() + step));
                let (south, north) = (frame.rows_at(rect.y0() - step), frame.rows_at(rect.y1() + step));
                let (i0, i1) = (i0.min(west[0]), i1.max(east[1]));
                let (j0, j1) = (j0.min(south[0]), j1.max(north[1]));
                let columns: Vec<usize> = (i0..=i1).collect();
                let rows: Vec<usize> = (j0..=j1).collect();
                let values = self.read(&columns, &rows)?;
                Ok(View::window(self.frame, [i0, j0], i1 - i0 + 1, values))
            }
            _ => {
                let n = steps + 1;
                // Each lattice position and a step either side (the normals'), and the two
                // samples either side of each.
                let read_at = |lo: f64, hi: f64, at: fn(&Frame, f64) -> [usize; 2]| {
                    let mut list: Vec<usize> = (0..n)
                        .map(|k| node_coordinate(k, n, lo, hi))
                        .flat_map(|c| [c - step, c, c + step])
                        .flat_map(|c| at(frame, c))
                        .collect();
                    list.sort_unstable();
                    list.dedup();
                    list
                };
                let columns = read_at(rect.x0(), rect.x1(), Frame::columns_at);
                let rows = read_at(rect.y0(), rect.y1(), Frame::rows_at);
                let values = self.read(&columns, &rows)?;
                Ok(View::sparse(self.frame, columns, rows, values))
            }
        }
    }

    /// The samples at `columns` × `rows` (each increasing), row by row, read block by block.
    fn read(&self, columns: &[usize], rows: &[usize]) -> Result<Vec<f64>, DemError> {
        let [bw, bh] = self.file.block_size();
        let [across, _] = self.file.blocks();
        let ny = self.frame.ny;
        let mut values = vec![0.0; columns.len() * rows.len()];
        // Each block once: the columns (and rows) one block holds are a run of the sorted list,
        // as (block, positions in the list).
        let runs = |list: &[usize], block: &dyn Fn(usize) -> usize| {
            let mut runs: Vec<(usize, std::ops::Range<usize>)> = Vec::new();
            for (at, &c) in list.iter().enumerate() {
                match runs.last_mut() {
                    Some((b, range)) if *b == block(c) => range.end = at + 1,
                    _ => runs.push((block(c), at..at + 1)),
                }
            }
            runs
        };
        // Image rows run down from the north.
        let (column_runs, row_runs) = (runs(columns, &|i| i / bw), runs(rows, &|j| (ny - 1 - j) / bh));
        for (by, row_ats) in &row_runs {
            for (bx, column_ats) in &column_runs {
                let block = self.block(by * across + bx, [*bx, *by])?;
                for b in row_ats.clone() {
                    let r = ny - 1 - rows[b] - by * bh;
                    let line = &block.values[r * block.size[0]..(r + 1) * block.size[0]];
                    for a in column_ats.clone() {
                        values[b * columns.len() + a] = line[columns[a] - bx * bw];
                    }
                }
            }
        }
        Ok(values)
    }

    /// Block `index` (at `[across, down]`), from the cache or the file.
    fn block(&self, index: usize, at: [usize; 2]) -> Result<Arc<Block>, DemError> {
        if let Some(block) = self.cache.get(&index) {
            return Ok(block);
        }
        let block = Arc::new(self.file.read(at, self.means[index])?);
        self.cache.insert(index, block.clone());
        Ok(block)
    }

    /// The bounds of the samples, in degrees.
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }

    /// The finer of the two sample spacings, in degrees.
    pub fn pixel(&self) -> f64 {
        let b = self.bounds;
        let dx = (b.east - b.west) / (self.frame.nx - 1) as f64;
        let dy = (b.north - b.south) / (self.frame.ny - 1) as f64;
        dx.min(dy)
    }
}

#[cfg(test)]
mod tests;
