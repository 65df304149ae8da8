//! Which format a grid file is, told from its first bytes.

use super::hints::{GridHints, raw_size};
use std::fmt;

/// The format [`decode_grid`](super::decode_grid) recognised.
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

pub(super) const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

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
pub(super) fn sniff(bytes: &[u8], hints: &GridHints) -> GridFileKind {
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
