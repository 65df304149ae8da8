//! [`decode_grid`]: the one entry point, which tells the format from the content and hands the
//! bytes to its decoder.

use super::error::GridFileError;
use super::hints::GridHints;
use super::kind::{GridFileKind, sniff};
use super::raw::decode_raw;
use super::tiff::{self, Crs};
use super::{json, npy, png};
use crate::geom::Rect;
use crate::source::Grid;

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
    /// The coordinate reference system of `domain`, when a GeoTIFF's keys name one.
    pub crs: Option<Crs>,
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
/// let hints = GridHints { nx: Some(3), ny: Some(2), dtype: Some(RawType::F32), ..GridHints::default() };
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
    let (grid, domain, crs) = match kind {
        GridFileKind::Tiff => tiff::decode(bytes, max_points)?,
        GridFileKind::Npy => (npy::decode(bytes, max_points)?, None, None),
        GridFileKind::Png => (png::decode(bytes, hints.encoding, max_points)?, None, None),
        GridFileKind::Json => (json::decode(bytes, max_points)?, None, None),
        GridFileKind::Raw => (decode_raw(bytes, hints, max_points)?, None, None),
    };
    Ok(DecodedGrid { grid, kind, domain, crs })
}
