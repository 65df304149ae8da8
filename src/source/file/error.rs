//! Why a grid file was refused, naming the sample (i, j) or the part of the file at fault.

use super::kind::GridFileKind;
use crate::geom::RectError;
use std::fmt;

/// Why a grid file was refused. Each variant says where: the format, the (i, j) of a bad
/// sample (see [`GridFileError::index`]), or the requested and allowed sizes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridFileError {
    /// The body has no bytes at all.
    #[error("grid file is empty")]
    Empty,
    /// The decoder gave up: the file is cut short or damaged.
    #[error("truncated or corrupt {kind} file: {detail}")]
    Corrupt {
        /// The format.
        kind: GridFileKind,
        /// What the decoder said (at most a few hundred characters).
        detail: String,
    },
    /// A sample type meshfit does not read.
    #[error("{kind} samples of type {found} are not supported; use {supported}")]
    UnsupportedType {
        /// The format.
        kind: GridFileKind,
        /// The file's sample type, as the format spells it.
        found: String,
        /// The types that are read.
        supported: &'static str,
    },
    /// A well-formed file that is not a grid meshfit reads (a 3-D array, say).
    #[error("{kind} file is not supported: {detail}")]
    Unsupported {
        /// The format.
        kind: GridFileKind,
        /// What is not supported.
        detail: String,
    },
    /// The data is longer or shorter than the header or the hints say.
    #[error("{kind} grid has {got} {unit}, but {from} need {expected}")]
    SizeMismatch {
        /// The format.
        kind: GridFileKind,
        /// "bytes of data" or "values".
        unit: &'static str,
        /// What sets the expected size: "the header's shape and dtype", "the hints nx, ny and
        /// dtype" or "nx and ny".
        from: &'static str,
        /// The size they need.
        expected: u64,
        /// The size the file has.
        got: u64,
    },
    /// A colour image where a greyscale heightmap is needed.
    #[error(
        "{kind} is {model} colour; send a greyscale heightmap, or give the encoding of an \
         elevation tile (terrain-rgb or terrarium)"
    )]
    Colour {
        /// The format.
        kind: GridFileKind,
        /// "RGB", "RGBA", "palette", "CMYK", "YCbCr", "CIELab" or "LogLuv".
        model: &'static str,
    },
    /// An encoding given for a file that is not an 8-bit RGB or RGBA PNG tile.
    #[error("encoding {encoding} is for 8-bit RGB or RGBA PNG tiles, not {found}")]
    NotATile {
        /// The encoding named.
        encoding: &'static str,
        /// What the file is: "a greyscale PNG", "a 16-bit RGB PNG", "an NPY file", ...
        found: String,
    },
    /// A TIFF with more than one sample per pixel.
    #[error("TIFF has {bands} bands (samples per pixel); send a single-band raster")]
    MultiBand {
        /// Samples per pixel.
        bands: u16,
    },
    /// A GeoTIFF sample equal to the file's `GDAL_NODATA` value.
    #[error(
        "sample at index [{i}, {j}] (file row {row}, column {i}) is the nodata value {value}; \
         fill the holes before meshing"
    )]
    NoData {
        /// Column (x index).
        i: usize,
        /// Row in meshfit's orientation (y index, upward).
        j: usize,
        /// Row as counted in the file, from its first row.
        row: usize,
        /// The nodata value.
        value: f64,
    },
    /// A GeoTIFF whose every sample is its `GDAL_NODATA` value: nothing to fill from.
    #[error("every sample is the nodata value {0}: the file holds no data")]
    AllNoData(f64),
    /// A PNG pixel that is not fully opaque.
    #[error(
        "PNG pixel at index [{i}, {j}] (file row {row}, column {i}) is transparent; \
         fill the holes before meshing"
    )]
    Transparent {
        /// Column (x index).
        i: usize,
        /// Row in meshfit's orientation (y index, upward).
        j: usize,
        /// Row as counted in the file, from its first row.
        row: usize,
    },
    /// An element of a JSON grid's values that is not a number.
    #[error("value at index [{i}, {j}] (values[{index}]) is {found}, not a number")]
    NotANumber {
        /// Column (x index).
        i: usize,
        /// Row (y index, upward: JSON lists the bottom row first).
        j: usize,
        /// Position in `values`.
        index: u64,
        /// What it is: "null", "a string", "a boolean", "an array" or "an object".
        found: &'static str,
    },
    /// A JSON grid's values nested as rows: they are one flat list.
    #[error(
        "values is a list of {rows} lists; send one flat list of nx*ny numbers, bottom row first \
         and x fastest (values[j*nx + i])"
    )]
    Nested {
        /// How many lists were sent.
        rows: u64,
    },
    /// A JSON grid's number beyond the range of f64 (`1e400`).
    #[error(
        "values[{index}]{} is beyond the range of a 64-bit float (magnitude above 1.8e308)",
        at.map_or(String::new(), |[i, j]| format!(" (index [{i}, {j}])"))
    )]
    OutOfRange {
        /// Position in `values`.
        index: u64,
        /// [i, j], when nx is known.
        at: Option<[usize; 2]>,
    },
    /// A NaN or infinite sample.
    #[error("{kind} sample at index [{i}, {j}] (file row {row}, column {i}) is not finite")]
    NonFinite {
        /// The format.
        kind: GridFileKind,
        /// Column (x index).
        i: usize,
        /// Row in meshfit's orientation (y index, upward).
        j: usize,
        /// Row as counted in the file, from its first row.
        row: usize,
    },
    /// nx·ny is above the caller's limit; refused before the samples are read.
    #[error("grid nx * ny is {requested} ({nx} x {ny}), above the limit of {allowed} points")]
    TooManyPoints {
        /// Samples along x the file declares.
        nx: u64,
        /// Samples along y the file declares.
        ny: u64,
        /// nx·ny, saturated at `u64::MAX`.
        requested: u64,
        /// The limit given to [`decode_grid`](super::decode_grid).
        allowed: usize,
    },
    /// Fewer than two samples along an axis.
    #[error("grid needs nx >= 2 and ny >= 2, got nx = {nx}, ny = {ny}")]
    TooFewPoints {
        /// Samples along x the file declares.
        nx: u64,
        /// Samples along y the file declares.
        ny: u64,
    },
    /// Raw data (no recognised header) without the hints that shape it.
    #[error(
        "not an NPY, PNG, TIFF or JSON grid, and raw samples need the hints nx, ny and dtype \
         (missing: {})",
        missing.join(", ")
    )]
    MissingHints {
        /// The hints not given, of "nx", "ny" and "dtype".
        missing: Vec<&'static str>,
    },
    /// A GeoTIFF's georeferencing that gives no valid rectangle.
    #[error("GeoTIFF domain: {0}")]
    Domain(RectError),
}

impl GridFileError {
    /// The [i, j] of the sample at fault, in meshfit's orientation (j upward), when one is.
    pub fn index(&self) -> Option<[usize; 2]> {
        match *self {
            GridFileError::NoData { i, j, .. }
            | GridFileError::Transparent { i, j, .. }
            | GridFileError::NotANumber { i, j, .. }
            | GridFileError::NonFinite { i, j, .. } => Some([i, j]),
            GridFileError::OutOfRange { at, .. } => at,
            _ => None,
        }
    }
}

/// A decoder's message, cut to a length an error response can carry: some decoders quote
/// the offending input.
pub(super) fn detail(message: impl fmt::Display) -> String {
    const MAX: usize = 300;
    let mut s = message.to_string();
    if s.len() > MAX {
        let mut end = MAX;
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        s.truncate(end);
        s.push('…');
    }
    s
}
