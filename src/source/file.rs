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
//! a NaN or infinite float each fail with the (i, j) of the first one in grid order. Terrain
//! tiles read a GeoTIFF by blocks instead ([`TiffBlocks`]), which fills its nodata samples
//! ([`fill_holes`]).
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

mod assemble;
mod blocks;
mod decode;
mod error;
mod fill;
mod hints;
mod json;
mod kind;
mod npy;
mod png;
mod raw;
#[cfg(test)]
mod tests;
mod tiff;

pub use blocks::{Block, BlockReader, TiffBlocks};
pub use decode::{DecodedGrid, decode_grid};
pub use error::GridFileError;
pub use fill::fill_holes;
pub use hints::{Encoding, GridHints, RawType};
pub use json::decode_values;
pub use kind::{GridFileKind, signed_kind};
pub use tiff::Crs;
