//! What every decoder shares: the size check before samples are allocated, the order rows
//! come in, holes, and the samples turned into a [`Grid`].

use super::error::GridFileError;
use super::kind::GridFileKind;
use crate::source::{Grid, GridError};

/// The first `N` bytes of `b` as an array (the callers pass chunks of exactly `N`).
pub(super) fn array<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&b[..N]);
    a
}

/// nx × ny samples, both at least 2, with nx·ny within the caller's limit.
#[derive(Debug, Clone, Copy)]
pub(super) struct Shape {
    pub(super) nx: usize,
    pub(super) ny: usize,
}

impl Shape {
    pub(super) fn points(self) -> usize {
        self.nx * self.ny
    }

    /// [i, j] of the sample at row-major position `index` (x fastest).
    pub(super) fn at(self, index: u64) -> [usize; 2] {
        [(index % self.nx as u64) as usize, (index / self.nx as u64) as usize]
    }
}

/// Checks a declared size before anything is allocated for it.
pub(super) fn check_size(nx: u64, ny: u64, max_points: usize) -> Result<Shape, GridFileError> {
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
pub(super) enum Rows {
    /// Images, .npy and raw: the first row is the top one, j = ny − 1.
    TopFirst,
    /// meshfit's JSON: the first row is j = 0.
    BottomFirst,
}

impl Rows {
    /// The file row that holds grid row `j`.
    pub(super) fn file_row(self, shape: Shape, j: usize) -> usize {
        match self {
            Rows::TopFirst => shape.ny - 1 - j,
            Rows::BottomFirst => j,
        }
    }
}

/// The first sample in grid order (j, then i, ascending) whose file index satisfies `bad`,
/// as (i, j, file row).
pub(super) fn find_in_grid_order(
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
pub(super) struct NoData(pub(super) f64);

impl NoData {
    pub(super) fn matches(self, v: f64) -> bool {
        if self.0.is_nan() { v.is_nan() } else { v == self.0 }
    }
}

/// Turns samples in file order into a grid: refuses nodata and non-finite samples (naming the
/// first in grid order), puts the bottom row first, and makes -0.0 into 0.0.
pub(super) fn into_grid(
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
pub(super) fn flip_rows<T>(values: &mut [T], shape: Shape) {
    let nx = shape.nx;
    for r in 0..shape.ny / 2 {
        let (top, bottom) = values.split_at_mut((shape.ny - 1 - r) * nx);
        top[r * nx..(r + 1) * nx].swap_with_slice(&mut bottom[..nx]);
    }
}
