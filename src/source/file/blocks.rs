//! A GeoTIFF read block by block — its tiles, or its strips — for a raster larger than memory:
//! the header once, then only the blocks a caller asks for.
//!
//! Nodata samples are filled within their own block (layer by layer from its data, see
//! [`fill_holes`]), so a sample's filled height depends on its block alone: the same whichever
//! blocks a caller reads, in whichever order. A block wholly nodata takes the height its
//! caller gives it.

use super::assemble::NoData;
use super::error::GridFileError;
use super::fill::fill_holes;
use super::tiff::{Crs, KIND, error, header, samples};
use crate::geom::Rect;
use ::tiff::decoder::{ChunkType, Decoder, Limits};
use std::io::{Read, Seek};
use std::sync::{Mutex, PoisonError};

/// What a block of samples can be read from: a file, or bytes in memory.
pub trait BlockReader: Read + Seek + Send {}

impl<R: Read + Seek + Send> BlockReader for R {}

/// A GeoTIFF opened for reading by blocks.
pub struct TiffBlocks {
    decoder: Mutex<Decoder<Box<dyn BlockReader>>>,
    size: [usize; 2],
    block: [usize; 2],
    nodata: Option<NoData>,
    domain: Option<Rect>,
    crs: Option<Crs>,
}

impl std::fmt::Debug for TiffBlocks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TiffBlocks").field("size", &self.size).field("block", &self.block).finish()
    }
}

/// One block's samples, image rows from the top, nodata filled.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// Columns and rows of data (an edge block may hold fewer than the file's block size).
    pub size: [usize; 2],
    /// `size[0]` samples a row, the top row first.
    pub values: Vec<f64>,
    /// Which samples were nodata, in the same order; `None` when none were.
    pub holes: Option<Vec<bool>>,
}

impl TiffBlocks {
    /// Opens the GeoTIFF `reader` holds, reading its header and tags only; at most
    /// `max_points` samples.
    ///
    /// # Errors
    /// When the header is not a TIFF meshfit reads (see `decode_grid`'s), or the file is
    /// larger than `max_points`.
    pub fn open(reader: Box<dyn BlockReader>, max_points: usize) -> Result<Self, GridFileError> {
        let mut decoder = Decoder::new(reader).map_err(error)?;
        let header = header(&mut decoder, max_points)?;
        let (w, h) = decoder.chunk_dimensions();
        let block = match decoder.get_chunk_type() {
            ChunkType::Tile => [w as usize, h as usize],
            // A strip spans the image's width whatever the chunk's width says.
            ChunkType::Strip => [header.shape.nx, (h as usize).min(header.shape.ny)],
        };
        if block[0] == 0 || block[1] == 0 {
            let detail = format!("blocks of {} x {} pixels", block[0], block[1]);
            return Err(GridFileError::Corrupt { kind: KIND, detail });
        }
        // A block decodes to at most its samples at 8 bytes: the default cap (256 MiB) would
        // refuse a large strip the whole-file decoder took.
        let bytes = block[0].saturating_mul(block[1]).saturating_mul(8);
        let mut limits = Limits::default();
        limits.decoding_buffer_size = limits.decoding_buffer_size.max(bytes);
        limits.intermediate_buffer_size = limits.intermediate_buffer_size.max(bytes);
        let decoder = decoder.with_limits(limits);
        Ok(Self {
            decoder: Mutex::new(decoder),
            size: [header.shape.nx, header.shape.ny],
            block,
            nodata: header.nodata,
            domain: header.domain,
            crs: header.crs,
        })
    }

    /// Columns and rows of the raster.
    pub fn size(&self) -> [usize; 2] {
        self.size
    }

    /// Columns and rows of a block (the last column and row of blocks may hold fewer).
    pub fn block_size(&self) -> [usize; 2] {
        self.block
    }

    /// Blocks across and down.
    pub fn blocks(&self) -> [usize; 2] {
        [self.size[0].div_ceil(self.block[0]), self.size[1].div_ceil(self.block[1])]
    }

    /// The rectangle through the centres of the corner pixels, when the file places them.
    pub fn domain(&self) -> Option<Rect> {
        self.domain
    }

    /// The coordinate system the file's keys name.
    pub fn crs(&self) -> Option<Crs> {
        self.crs
    }

    /// The `GDAL_NODATA` value, if the file has one.
    pub fn nodata(&self) -> Option<f64> {
        self.nodata.map(|n| n.0)
    }

    /// Block `[across, down]` (from the top left), its nodata filled from its data; when it
    /// has none, every sample is `empty`.
    ///
    /// # Errors
    /// When the block cannot be read or decoded, or holds a non-finite sample that is not
    /// nodata (named by its pixel).
    ///
    /// # Panics
    /// When the block is outside [`TiffBlocks::blocks`].
    pub fn read(&self, [bx, by]: [usize; 2], empty: f64) -> Result<Block, GridFileError> {
        let [across, down] = self.blocks();
        assert!(bx < across && by < down, "block [{bx}, {by}] of {across} x {down}");
        let index = u32::try_from(by * across + bx).map_err(|_| GridFileError::Corrupt {
            kind: KIND,
            detail: "more blocks than a TIFF indexes".into(),
        })?;
        let mut decoder = self.decoder.lock().unwrap_or_else(PoisonError::into_inner);
        let (w, h) = decoder.chunk_data_dimensions(index);
        let mut values = samples(decoder.read_chunk(index).map_err(error)?)?;
        drop(decoder);
        let size = [w as usize, h as usize];
        if values.len() != size[0] * size[1] {
            let detail = format!("block {index} decoded {} samples for {w} x {h} pixels", values.len());
            return Err(GridFileError::Corrupt { kind: KIND, detail });
        }
        let hole = |v: f64| self.nodata.is_some_and(|n| n.matches(v));
        if let Some(k) = values.iter().position(|&v| !v.is_finite() && !hole(v)) {
            let (i, row) = (bx * self.block[0] + k % size[0], by * self.block[1] + k / size[0]);
            return Err(GridFileError::NonFinite { kind: KIND, i, j: self.size[1] - 1 - row, row });
        }
        let holes = match self.nodata {
            Some(nodata) if values.iter().any(|&v| nodata.matches(v)) => {
                Some(fill_holes(&mut values, size, hole).unwrap_or_else(|| {
                    values.fill(empty);
                    vec![true; values.len()]
                }))
            }
            _ => None,
        };
        Ok(Block { size, values, holes })
    }
}
