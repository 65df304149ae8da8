//! Grid files (.npy, PNG, TIFF/GeoTIFF, raw samples, meshfit's JSON) decoded into a [`Grid`].
//!
//! [`decode_grid`] is the one entry point for the command line and the API: it tells the
//! format from the content, never from a file name, checks the declared size against a limit
//! before it allocates the samples, and names the (i, j) of any sample it refuses.
//!
//! # Orientation
//! A [`Grid`] holds `values[j·nx + i] = F(x_i, y_j)` with y increasing upward. Images list
//! their rows from the top down, so in a PNG or TIFF the image row r becomes j = ny − 1 − r:
//! north stays up. A 2-D .npy array of shape (rows, columns) = (ny, nx) and raw samples are
//! read the same way, row 0 at the top, because heightmaps made with numpy (or dumped with
//! `tofile`) follow the image convention. Only the JSON form lists its rows bottom first, as
//! meshfit's API always has. Errors name (i, j) in meshfit's orientation and also the row as
//! counted in the file.
//!
//! # Formats
//! | content starts with | format | samples |
//! | --- | --- | --- |
//! | `\x93NUMPY` | .npy (version 1–3) | 2-D, C or Fortran order, `f4 f8 i1 u1 i2 u2 i4 u4`, either byte order |
//! | PNG signature | PNG | 8- or 16-bit greyscale, with or without alpha; 8-bit RGB or RGBA with an [`Encoding`] |
//! | `II*\0`, `MM\0*` (or BigTIFF's `+`) | TIFF, GeoTIFF | one band of `u8 u16 u32 i8 i16 i32 f32 f64` |
//! | `{` after whitespace | JSON `{"nx": .., "ny": .., "values": [..]}` | numbers, bottom row first |
//! | anything else | raw little-endian `f32` or `f64` | needs the `nx`, `ny` and `dtype` hints |
//!
//! A body that starts with `{` is raw data, not JSON, when all three raw hints are given and
//! its length is exactly nx·ny·(4|8): the first byte of a raw float is `{` one time in 256.
//! Hints are ignored for the formats whose header states the size.
//!
//! Every accepted sample type converts to f64 exactly; -0.0 becomes 0.0. Integer samples are
//! taken as they are (a 16-bit PNG gives 0 to 65535): scaling z is the caller's business. A
//! colour PNG is a web-map elevation tile only when the hints name its [`Encoding`]
//! (Terrain-RGB or Terrarium); without one it is refused, and an encoding is refused for
//! anything but an 8-bit RGB or RGBA PNG.
//!
//! # Holes
//! A hole is an error, not a guess: a GeoTIFF sample equal to its `GDAL_NODATA` value, a PNG
//! pixel that is not fully opaque (alpha below its maximum, or equal to the `tRNS` grey), and
//! a NaN or infinite float each fail with the (i, j) of the first one in grid order.
//!
//! # GeoTIFF domain
//! `ModelPixelScale` (33550) with `ModelTiepoint` (33922), or an axis-aligned
//! `ModelTransformation` (34264), give [`DecodedGrid::domain`]: the rectangle through the
//! centres of the corner pixels, x from the left column to the right one, y from the bottom row
//! to the top one. `GTRasterTypeGeoKey` says whether the tie point is a pixel's corner
//! (PixelIsArea, the default: the centre is half a pixel in) or its centre (PixelIsPoint).
//! A rotated transformation or ground control points without a scale give no domain; a
//! negative pixel size (a south-up raster) is refused rather than flipped.
//!
//! # Limitations
//! Only the first image of a TIFF or an animated PNG is read. TIFF alpha counts as a second
//! band, and a WhiteIsZero TIFF is refused rather than inverted. Greyscale PNGs of 1, 2 or 4
//! bits, f16 and 64-bit integer TIFFs, and complex or 64-bit integer .npy arrays are refused:
//! f16 is rare in heightmaps, and a 64-bit integer does not always fit an f64 exactly.

mod json;

pub use json::decode_values;
mod npy;
mod png;
mod tiff;

use super::{Grid, GridError};
use crate::geom::{Rect, RectError};
use std::fmt;

/// What a raw file cannot say about itself. Ignored for formats whose header states the size.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GridHints {
    /// Samples along x (columns).
    pub nx: Option<usize>,
    /// Samples along y (rows).
    pub ny: Option<usize>,
    /// The sample type of raw data.
    pub dtype: Option<RawType>,
    /// How a colour PNG tile encodes heights.
    pub encoding: Option<Encoding>,
}

/// How a web-map elevation tile (an 8-bit RGB or RGBA PNG) encodes each pixel's height.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Encoding {
    /// Mapbox Terrain-RGB: height = −10000 + (R·65536 + G·256 + B) · 0.1 metres.
    TerrainRgb,
    /// Terrarium (Mapzen, AWS Terrain Tiles): height = R·256 + G + B/256 − 32768 metres.
    Terrarium,
}

impl Encoding {
    /// `"terrain-rgb"` or `"terrarium"`, as the API spells it.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::TerrainRgb => "terrain-rgb",
            Encoding::Terrarium => "terrarium",
        }
    }

    /// The encoding `name` spells, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        [Encoding::TerrainRgb, Encoding::Terrarium].into_iter().find(|e| e.name() == name)
    }

    /// The height of a pixel of colour (r, g, b). Exact in f64 but for Terrain-RGB's tenths,
    /// which are the nearest f64 to the decimal height (an integer count of tenths, divided).
    #[inline]
    pub fn height(self, [r, g, b]: [u8; 3]) -> f64 {
        let (r, g, b) = (u32::from(r), u32::from(g), u32::from(b));
        match self {
            Encoding::TerrainRgb => f64::from((r << 16 | g << 8 | b) as i32 - 100_000) / 10.0,
            Encoding::Terrarium => f64::from(r * 256 + g) - 32768.0 + f64::from(b) / 256.0,
        }
    }
}

/// The sample type of raw data: little-endian IEEE floats, rows from the top down.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RawType {
    /// 4-byte little-endian IEEE 754 floats.
    F32,
    /// 8-byte little-endian IEEE 754 floats.
    F64,
}

impl RawType {
    /// `"f32"` or `"f64"`, as the API spells it.
    pub fn name(self) -> &'static str {
        match self {
            RawType::F32 => "f32",
            RawType::F64 => "f64",
        }
    }

    /// The type `name` spells (`"f32"` or `"f64"`), if any.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "f32" => Some(RawType::F32),
            "f64" => Some(RawType::F64),
            _ => None,
        }
    }

    /// Bytes per sample: 4 or 8.
    pub fn size(self) -> usize {
        match self {
            RawType::F32 => 4,
            RawType::F64 => 8,
        }
    }
}

/// The format [`decode_grid`] recognised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GridFileKind {
    /// A NumPy .npy array.
    Npy,
    /// A PNG image.
    Png,
    /// A TIFF or GeoTIFF raster (BigTIFF too).
    Tiff,
    /// Headerless little-endian floats, shaped by [`GridHints`].
    Raw,
    /// `{"nx": .., "ny": .., "values": [..]}`.
    Json,
}

impl GridFileKind {
    /// The format's name for messages: "NPY", "PNG", "TIFF", "raw" or "JSON".
    pub fn name(self) -> &'static str {
        match self {
            GridFileKind::Npy => "NPY",
            GridFileKind::Png => "PNG",
            GridFileKind::Tiff => "TIFF",
            GridFileKind::Raw => "raw",
            GridFileKind::Json => "JSON",
        }
    }
}

impl fmt::Display for GridFileKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A decoded grid file.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedGrid {
    /// The samples, over their default domain [0, nx−1] × [0, ny−1].
    pub grid: Grid,
    /// The format the content was recognised as.
    pub kind: GridFileKind,
    /// The rectangle a GeoTIFF places the samples on, when it says so; apply it with
    /// [`Grid::with_domain`] unless the request names its own.
    pub domain: Option<Rect>,
}

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
        /// The limit given to [`decode_grid`].
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

/// Decodes a grid file of any supported format into a [`Grid`].
///
/// The format comes from the content (see the module docs); `hints` shape raw data;
/// `max_points` bounds nx·ny and is checked against the header before the samples are
/// decoded or allocated.
///
/// # Errors
/// A [`GridFileError`] naming the format and, for a bad sample, its (i, j): a truncated or
/// corrupt file, an unsupported sample type, a colour image, a multi-band TIFF, a nodata,
/// transparent or non-finite sample, a size that does not match the header or the hints,
/// nx·ny above `max_points`, nx or ny below 2, or raw data without hints.
///
/// # Example
/// ```
/// use meshfit::source::{GridFileKind, GridHints, RawType, decode_grid};
///
/// // Two rows of three f32 samples, the top row first.
/// let samples = [4.0f32, 5.0, 6.0, 1.0, 2.0, 3.0];
/// let bytes: Vec<u8> = samples.iter().flat_map(|v| v.to_le_bytes()).collect();
/// let hints = GridHints { nx: Some(3), ny: Some(2), dtype: Some(RawType::F32), encoding: None };
/// let decoded = decode_grid(&bytes, &hints, 1 << 20).unwrap();
/// assert_eq!(decoded.kind, GridFileKind::Raw);
/// assert_eq!(decoded.grid.row(0), &[1.0, 2.0, 3.0]); // j = 0 is the bottom row
/// ```
pub fn decode_grid(bytes: &[u8], hints: &GridHints, max_points: usize) -> Result<DecodedGrid, GridFileError> {
    if bytes.is_empty() {
        return Err(GridFileError::Empty);
    }
    let kind = sniff(bytes, hints);
    if let Some(encoding) = hints.encoding.filter(|_| kind != GridFileKind::Png) {
        let found = format!("a{} {kind} file", if kind == GridFileKind::Npy { "n" } else { "" });
        return Err(GridFileError::NotATile { encoding: encoding.name(), found });
    }
    let (grid, domain) = match kind {
        GridFileKind::Npy => (npy::decode(bytes, max_points)?, None),
        GridFileKind::Png => (png::decode(bytes, hints.encoding, max_points)?, None),
        GridFileKind::Tiff => tiff::decode(bytes, max_points)?,
        GridFileKind::Json => (json::decode(bytes, max_points)?, None),
        GridFileKind::Raw => (decode_raw(bytes, hints, max_points)?, None),
    };
    Ok(DecodedGrid { grid, kind, domain })
}

const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

/// The format of a file that says what it is in its first bytes: NPY, PNG or TIFF.
pub fn signed_kind(bytes: &[u8]) -> Option<GridFileKind> {
    if bytes.starts_with(b"\x93NUMPY") {
        return Some(GridFileKind::Npy);
    }
    if bytes.starts_with(PNG_SIGNATURE) {
        return Some(GridFileKind::Png);
    }
    // Classic TIFF has 42 ('*') after the byte order, BigTIFF 43 ('+').
    if [b"II*\0", b"MM\0*", b"II+\0", b"MM\0+"].iter().any(|m| bytes.starts_with(*m)) {
        return Some(GridFileKind::Tiff);
    }
    None
}

/// The format of `bytes`, from its first bytes (and, for `{`, the raw hints).
fn sniff(bytes: &[u8], hints: &GridHints) -> GridFileKind {
    if let Some(kind) = signed_kind(bytes) {
        return kind;
    }
    if raw_size(hints) == Some(bytes.len() as u64) {
        return GridFileKind::Raw;
    }
    match bytes.iter().find(|b| !b" \t\r\n".contains(b)) {
        Some(b'{') => GridFileKind::Json,
        _ => GridFileKind::Raw,
    }
}

/// nx·ny·(4|8) when all three raw hints are given.
fn raw_size(hints: &GridHints) -> Option<u64> {
    let (nx, ny, dtype) = (hints.nx?, hints.ny?, hints.dtype?);
    (nx as u64).checked_mul(ny as u64)?.checked_mul(dtype.size() as u64)
}

fn decode_raw(bytes: &[u8], hints: &GridHints, max_points: usize) -> Result<Grid, GridFileError> {
    let (Some(nx), Some(ny), Some(dtype)) = (hints.nx, hints.ny, hints.dtype) else {
        let given =
            [("nx", hints.nx.is_some()), ("ny", hints.ny.is_some()), ("dtype", hints.dtype.is_some())];
        let missing = given.iter().filter(|(_, has)| !has).map(|(name, _)| *name).collect();
        return Err(GridFileError::MissingHints { missing });
    };
    let shape = check_size(nx as u64, ny as u64, max_points)?;
    // Saturates only for a limit near usize::MAX, where no file can match anyway.
    let expected = (shape.points() as u64).saturating_mul(dtype.size() as u64);
    if bytes.len() as u64 != expected {
        return Err(GridFileError::SizeMismatch {
            kind: GridFileKind::Raw,
            unit: "bytes of data",
            from: "the hints nx, ny and dtype",
            expected,
            got: bytes.len() as u64,
        });
    }
    let values = match dtype {
        RawType::F32 => bytes.chunks_exact(4).map(|b| f64::from(f32::from_le_bytes(array(b)))).collect(),
        RawType::F64 => bytes.chunks_exact(8).map(|b| f64::from_le_bytes(array(b))).collect(),
    };
    into_grid(GridFileKind::Raw, shape, Rows::TopFirst, values, None)
}

/// The first `N` bytes of `b` as an array (the callers pass chunks of exactly `N`).
fn array<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&b[..N]);
    a
}

/// nx × ny samples, both at least 2, with nx·ny within the caller's limit.
#[derive(Debug, Clone, Copy)]
struct Shape {
    nx: usize,
    ny: usize,
}

impl Shape {
    fn points(self) -> usize {
        self.nx * self.ny
    }

    /// [i, j] of the sample at row-major position `index` (x fastest).
    fn at(self, index: u64) -> [usize; 2] {
        [(index % self.nx as u64) as usize, (index / self.nx as u64) as usize]
    }
}

/// Checks a declared size before anything is allocated for it.
fn check_size(nx: u64, ny: u64, max_points: usize) -> Result<Shape, GridFileError> {
    if nx < 2 || ny < 2 {
        return Err(GridFileError::TooFewPoints { nx, ny });
    }
    let requested = nx.saturating_mul(ny);
    if requested > max_points as u64 {
        return Err(GridFileError::TooManyPoints { nx, ny, requested, allowed: max_points });
    }
    // Both fit in usize: each is at most nx·ny ≤ max_points.
    Ok(Shape { nx: nx as usize, ny: ny as usize })
}

/// Which row a file lists first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rows {
    /// Images, .npy and raw: the first row is the top one, j = ny − 1.
    TopFirst,
    /// meshfit's JSON: the first row is j = 0.
    BottomFirst,
}

impl Rows {
    /// The file row that holds grid row `j`.
    fn file_row(self, shape: Shape, j: usize) -> usize {
        match self {
            Rows::TopFirst => shape.ny - 1 - j,
            Rows::BottomFirst => j,
        }
    }
}

/// The first sample in grid order (j, then i, ascending) whose file index satisfies `bad`,
/// as (i, j, file row).
fn find_in_grid_order(
    shape: Shape,
    rows: Rows,
    mut bad: impl FnMut(usize) -> bool,
) -> Option<(usize, usize, usize)> {
    (0..shape.ny).find_map(|j| {
        let row = rows.file_row(shape, j);
        (0..shape.nx).find(|&i| bad(row * shape.nx + i)).map(|i| (i, j, row))
    })
}

/// A sample value that marks a hole, compared the way GDAL does: NaN matches NaN.
#[derive(Debug, Clone, Copy)]
struct NoData(f64);

impl NoData {
    fn matches(self, v: f64) -> bool {
        if self.0.is_nan() { v.is_nan() } else { v == self.0 }
    }
}

/// Turns samples in file order into a grid: refuses nodata and non-finite samples (naming the
/// first in grid order), puts the bottom row first, and makes -0.0 into 0.0.
fn into_grid(
    kind: GridFileKind,
    shape: Shape,
    rows: Rows,
    mut values: Vec<f64>,
    nodata: Option<NoData>,
) -> Result<Grid, GridFileError> {
    debug_assert_eq!(values.len(), shape.points());
    let is_hole = |v: f64| nodata.is_some_and(|n| n.matches(v));
    if let Some((i, j, row)) =
        find_in_grid_order(shape, rows, |k| is_hole(values[k]) || !values[k].is_finite())
    {
        let v = values[row * shape.nx + i];
        return Err(match nodata {
            Some(n) if n.matches(v) => GridFileError::NoData { i, j, row, value: n.0 },
            _ => GridFileError::NonFinite { kind, i, j, row },
        });
    }
    if rows == Rows::TopFirst {
        flip_rows(&mut values, shape);
    }
    // One value, one cache key, whichever format carried the grid.
    values.iter_mut().for_each(|v| *v += 0.0);
    Grid::new(shape.nx, shape.ny, values).map_err(|e: GridError| GridFileError::Corrupt {
        // Unreachable: the size and every value were checked above.
        kind,
        detail: e.to_string(),
    })
}

/// Reverses the order of the rows in place.
fn flip_rows(values: &mut [f64], shape: Shape) {
    let nx = shape.nx;
    for r in 0..shape.ny / 2 {
        let (top, bottom) = values.split_at_mut((shape.ny - 1 - r) * nx);
        top[r * nx..(r + 1) * nx].swap_with_slice(&mut bottom[..nx]);
    }
}

/// A decoder's message, cut to a length an error response can carry: some decoders quote
/// the offending input.
fn detail(message: impl fmt::Display) -> String {
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

#[cfg(test)]
mod tests;
