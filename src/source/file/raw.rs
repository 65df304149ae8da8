//! Raw little-endian samples, sized by the caller's hints.

use super::assemble::{Rows, array, check_size, into_grid};
use super::error::GridFileError;
use super::hints::{GridHints, RawType};
use super::kind::GridFileKind;
use crate::source::Grid;

/// The samples of a raw file, sized and typed by `hints`, row 0 at the top.
pub(super) fn decode_raw(bytes: &[u8], hints: &GridHints, max_points: usize) -> Result<Grid, GridFileError> {
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
