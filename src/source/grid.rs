//! A function sampled on a regular grid, bilinear between nodes.

use crate::geom::{Point, Rect};

/// nx × ny samples of F on a rectangle, row-major with x fastest:
/// `values[j·nx + i] = F(x_i, y_j)` with `x_i = a + i·(b−a)/(nx−1)` and `y_j` likewise.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    nx: usize,
    ny: usize,
    values: Vec<f64>,
    rect: Rect,
    /// The smallest and largest value of each run of [`BLOCK`] nodes of each row, so that a
    /// scan for the largest error can pass over runs that cannot hold it.
    blocks: Vec<(f64, f64)>,
}

/// Nodes per run of a row whose value range [`Grid::block_range`] keeps: 16 bytes per 32
/// nodes (half a byte a node) for a bound that lets error scans skip most of a smooth grid.
pub const BLOCK: usize = 32;

/// Why a grid was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// Fewer than two nodes on an axis.
    #[error("grid needs nx >= 2 and ny >= 2, got nx = {nx}, ny = {ny}")]
    TooSmall {
        /// Nodes along x.
        nx: usize,
        /// Nodes along y.
        ny: usize,
    },
    /// `values` does not hold nx·ny numbers.
    #[error("grid has {got} values, but nx * ny = {expected}")]
    LengthMismatch {
        /// nx·ny.
        expected: usize,
        /// values.len().
        got: usize,
    },
    /// A value is NaN or infinite.
    #[error("grid value at index [{i}, {j}] (values[{index}]) is not finite")]
    NonFinite {
        /// Column (x index).
        i: usize,
        /// Row (y index).
        j: usize,
        /// Position in `values`.
        index: usize,
    },
}

impl Grid {
    /// A grid over its default domain [0, nx−1] × [0, ny−1].
    ///
    /// # Errors
    /// When nx or ny is below 2, when `values.len() != nx·ny`, or when a value is not finite
    /// (the error names its (i, j)).
    pub fn new(nx: usize, ny: usize, values: Vec<f64>) -> Result<Self, GridError> {
        if nx < 2 || ny < 2 {
            return Err(GridError::TooSmall { nx, ny });
        }
        let expected = nx.saturating_mul(ny);
        if values.len() != expected {
            return Err(GridError::LengthMismatch { expected, got: values.len() });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(GridError::NonFinite { i: index % nx, j: index / nx, index });
        }
        let blocks = values
            .chunks_exact(nx)
            .flat_map(|row| row.chunks(BLOCK))
            .map(|run| {
                run.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
            })
            .collect();
        let mut grid = Self { nx, ny, values, rect: Rect::unit(), blocks };
        grid.rect = grid.default_domain();
        Ok(grid)
    }

    /// The same samples spread over `rect` instead.
    pub fn with_domain(mut self, rect: Rect) -> Self {
        self.rect = rect;
        self
    }

    /// [0, nx−1] × [0, ny−1].
    pub fn default_domain(&self) -> Rect {
        Rect::new(0.0, (self.nx - 1) as f64, 0.0, (self.ny - 1) as f64).expect("valid grid size")
    }

    /// The rectangle the samples cover.
    pub fn rect(&self) -> Rect {
        self.rect
    }

    /// Nodes along x.
    pub fn nx(&self) -> usize {
        self.nx
    }

    /// Nodes along y.
    pub fn ny(&self) -> usize {
        self.ny
    }

    /// The sample at node (i, j).
    #[inline]
    pub fn value(&self, i: usize, j: usize) -> f64 {
        self.values[j * self.nx + i]
    }

    /// The samples of row j, x fastest.
    #[inline]
    pub fn row(&self, j: usize) -> &[f64] {
        &self.values[j * self.nx..(j + 1) * self.nx]
    }

    /// The smallest and largest value of nodes `b·BLOCK .. (b+1)·BLOCK` of row j (fewer at
    /// the row's end).
    #[inline]
    pub fn block_range(&self, j: usize, b: usize) -> (f64, f64) {
        self.blocks[j * self.nx.div_ceil(BLOCK) + b]
    }

    /// Position of node (i, j); the last node of a row or column is exactly on the far side.
    #[inline]
    pub fn node(&self, i: usize, j: usize) -> Point {
        let r = self.rect;
        Point::new(node_coordinate(i, self.nx, r.x0(), r.x1()), node_coordinate(j, self.ny, r.y0(), r.y1()))
    }

    /// Continuous grid coordinates of `p`: node (i, j) is at (i, j).
    #[inline]
    pub fn to_grid(&self, p: Point) -> (f64, f64) {
        let r = self.rect;
        (grid_coordinate(p.x, self.nx, r.x0(), r.x1()), grid_coordinate(p.y, self.ny, r.y0(), r.y1()))
    }
}

/// The continuous index of coordinate `x` among `n` nodes spread over [`lo`, `hi`]: what
/// [`Grid::to_grid`] gives on each axis. For a caller that holds only part of a grid's values.
#[inline]
pub fn grid_coordinate(x: f64, n: usize, lo: f64, hi: f64) -> f64 {
    (x - lo) / (hi - lo) * to_f64(n - 1)
}

/// The coordinate of node `k` of `n` spread over [`lo`, `hi`]: what [`Grid::node`] gives on
/// each axis, the last node exactly at `hi`. For a caller that needs a grid's node positions
/// before it has the grid's values.
#[inline]
pub fn node_coordinate(k: usize, n: usize, lo: f64, hi: f64) -> f64 {
    if k == n - 1 { hi } else { lo + k as f64 * ((hi - lo) / (n - 1) as f64) }
}

/// A count as an f64, the same number as `n as f64`: through i64, which x86-64 converts in
/// one instruction where an unsigned 64-bit integer takes several (a Vec's length is below
/// 2^63, and both conversions round alike).
#[inline]
fn to_f64(n: usize) -> f64 {
    n as i64 as f64
}

/// Splits a continuous grid coordinate into a cell index in [0, n−2] and a fraction.
#[inline]
pub(crate) fn cell(u: f64, n: usize) -> (usize, f64) {
    // Comparisons rather than `clamp`, which checks its bounds first: the same value, NaN
    // included.
    let last = to_f64(n - 1);
    let u = if u < 0.0 { 0.0 } else { u };
    let u = if u > last { last } else { u };
    // `as` truncates, which is floor for u ≥ 0 without a call (SSE2 has no rounding op).
    let i = (u as i64 as usize).min(n - 2);
    (i, u - to_f64(i))
}

impl Grid {
    /// F at `p`: bilinear interpolation in the cell that holds `p` (clamped to the grid).
    #[inline]
    pub fn interpolate(&self, p: Point) -> f64 {
        let (u, v) = self.to_grid(p);
        let (i, fx) = cell(u, self.nx);
        let (j, fy) = cell(v, self.ny);
        let row = j * self.nx + i;
        // A slice per row of the cell: two bounds checks instead of four.
        let (low, high) = (&self.values[row..row + 2], &self.values[row + self.nx..row + self.nx + 2]);
        // Weighted sums rather than z0 + (z1 - z0)·t: the difference of two finite values
        // near ±f64::MAX overflows.
        let bottom = low[0] * (1.0 - fx) + low[1] * fx;
        let top = high[0] * (1.0 - fx) + high[1] * fx;
        bottom * (1.0 - fy) + top * fy
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::Surface;

    #[test]
    fn grid_errors_name_the_problem_and_the_bad_index() {
        assert_eq!(Grid::new(1, 5, vec![0.0; 5]), Err(GridError::TooSmall { nx: 1, ny: 5 }));
        assert_eq!(Grid::new(3, 2, vec![0.0; 5]), Err(GridError::LengthMismatch { expected: 6, got: 5 }));
        let mut values = vec![0.0; 6];
        values[5] = f64::INFINITY;
        let err = Grid::new(3, 2, values).unwrap_err();
        assert_eq!(err, GridError::NonFinite { i: 2, j: 1, index: 5 });
        assert_eq!(err.to_string(), "grid value at index [2, 1] (values[5]) is not finite");
    }

    #[test]
    fn bilinear_interpolation_hits_nodes_and_is_exact_on_bilinear_data() {
        // F(x, y) = 1 + 2x + 3y + 4xy sampled on [0, 2] x [0, 1] with 5 x 3 nodes.
        let f = |x: f64, y: f64| 1.0 + 2.0 * x + 3.0 * y + 4.0 * x * y;
        let (nx, ny) = (5, 3);
        let rect = Rect::new(0.0, 2.0, 0.0, 1.0).unwrap();
        let values = (0..ny).flat_map(|j| (0..nx).map(move |i| f(i as f64 * 0.5, j as f64 * 0.5))).collect();
        let grid = Grid::new(nx, ny, values).unwrap().with_domain(rect);
        for j in 0..ny {
            for i in 0..nx {
                assert_eq!(grid.eval(grid.node(i, j)), grid.value(i, j), "node ({i}, {j})");
            }
        }
        for p in [Point::new(0.3, 0.7), Point::new(1.99, 0.01), Point::new(2.0, 1.0)] {
            assert!((grid.eval(p) - f(p.x, p.y)).abs() < 1e-12, "at {p:?}");
        }
    }

    #[test]
    fn interpolation_does_not_overflow_between_huge_values_of_opposite_sign() {
        let grid = Grid::new(2, 2, vec![-1e308, 1e308, 0.0, 0.0]).unwrap();
        assert_eq!(grid.eval(Point::new(0.0, 0.0)), -1e308);
        assert_eq!(grid.eval(Point::new(0.5, 0.0)), 0.0);
        assert!(grid.eval(Point::new(0.25, 0.5)).is_finite());
    }

    #[test]
    fn block_ranges_hold_the_extremes_of_their_runs() {
        let (nx, ny) = (2 * BLOCK + 5, 3);
        let values: Vec<f64> = (0..nx * ny).map(|k| ((k * 7919) % 101) as f64 - 50.0).collect();
        let grid = Grid::new(nx, ny, values).unwrap();
        for j in 0..ny {
            for b in 0..nx.div_ceil(BLOCK) {
                let run = &grid.row(j)[b * BLOCK..((b + 1) * BLOCK).min(nx)];
                let lo = run.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = run.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                assert_eq!(grid.block_range(j, b), (lo, hi), "row {j}, block {b}");
            }
        }
    }

    #[test]
    fn default_domain_is_the_index_range() {
        let grid = Grid::new(4, 3, vec![0.0; 12]).unwrap();
        assert_eq!(grid.rect(), Rect::new(0.0, 3.0, 0.0, 2.0).unwrap());
        assert_eq!(grid.node(3, 2), Point::new(3.0, 2.0));
    }
}
