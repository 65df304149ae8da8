//! The samples of a DEM one tile reads: all of them for a grid in memory, else a window of
//! them, or for a low level's tile of a large DEM only those its lattice interpolates.
//!
//! Every view indexes samples and places points in the whole DEM's frame, with the same
//! arithmetic as [`Grid::interpolate`]: a height is the same bits whichever samples a view
//! holds, so two tiles that read different windows agree on their shared side.

use crate::geom::{Point, Rect};
use crate::source::{Grid, cell, grid_coordinate, node_coordinate};

/// The most samples of a DEM a tile copies to measure itself at: 32 MiB. A low level's tile of
/// a large DEM (16.8 million samples at the default limit) is measured at its lattice alone,
/// for a tolerance of kilometres.
pub const MAX_SAMPLES: usize = 1 << 22;

/// Where a DEM's samples are: nx × ny nodes over `rect`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Columns.
    pub nx: usize,
    /// Rows, from the south.
    pub ny: usize,
    /// The rectangle through the corner samples, in degrees.
    pub rect: Rect,
}

impl Frame {
    /// The continuous column of longitude `x`.
    pub(super) fn u(&self, x: f64) -> f64 {
        grid_coordinate(x, self.nx, self.rect.x0(), self.rect.x1())
    }

    /// The continuous row of latitude `y`.
    pub(super) fn v(&self, y: f64) -> f64 {
        grid_coordinate(y, self.ny, self.rect.y0(), self.rect.y1())
    }

    /// The columns an interpolation at longitude `x` reads.
    pub(super) fn columns_at(&self, x: f64) -> [usize; 2] {
        let (i, _) = cell(self.u(x), self.nx);
        [i, i + 1]
    }

    /// The rows an interpolation at latitude `y` reads.
    pub(super) fn rows_at(&self, y: f64) -> [usize; 2] {
        let (j, _) = cell(self.v(y), self.ny);
        [j, j + 1]
    }

    /// The samples inside `rect` at least `clearance` from its sides, as inclusive columns
    /// and rows `[i0, i1, j0, j1]`; `None` when fewer than one a side are.
    pub(super) fn inside(&self, rect: Rect, clearance: f64) -> Option<[usize; 4]> {
        let r = self.rect;
        let (x0, x1) = (rect.x0() + clearance, rect.x1() - clearance);
        let (y0, y1) = (rect.y0() + clearance, rect.y1() - clearance);
        // Candidates from the continuous indices, a node's rounding either way; then each
        // node's own position decides.
        let span = |lo: f64, hi: f64, n: usize| {
            let first = (lo.floor() - 2.0).clamp(0.0, (n - 1) as f64) as usize;
            let last = (hi.ceil() + 2.0).clamp(0.0, (n - 1) as f64) as usize;
            first..=last
        };
        let column_in = |&i: &usize| (x0..=x1).contains(&node_coordinate(i, self.nx, r.x0(), r.x1()));
        let row_in = |&j: &usize| (y0..=y1).contains(&node_coordinate(j, self.ny, r.y0(), r.y1()));
        let (mut columns, mut rows) =
            (span(self.u(x0), self.u(x1), self.nx), span(self.v(y0), self.v(y1), self.ny));
        let [i0, i1] = [columns.clone().find(column_in)?, columns.rfind(column_in)?];
        Some([i0, i1, rows.clone().find(row_in)?, rows.rfind(row_in)?])
    }
}

/// How many samples inclusive ranges `[i0, i1, j0, j1]` hold.
pub(super) fn count([i0, i1, j0, j1]: [usize; 4]) -> usize {
    (i1 - i0 + 1).saturating_mul(j1 - j0 + 1)
}

/// The samples of a DEM a tile reads.
#[derive(Debug)]
pub struct View<'a> {
    frame: Frame,
    samples: Samples<'a>,
}

#[derive(Debug)]
enum Samples<'a> {
    /// Every sample, in a grid.
    Whole(&'a Grid),
    /// Columns `i0..i0 + width` of rows from `j0`, row by row.
    Window { i0: usize, j0: usize, width: usize, values: Vec<f64> },
    /// The samples at these columns and rows (each increasing), row by row.
    Sparse { columns: Vec<usize>, rows: Vec<usize>, values: Vec<f64> },
}

impl<'a> View<'a> {
    /// Every sample of `grid`, whose domain is in degrees.
    pub fn whole(grid: &'a Grid) -> Self {
        let frame = Frame { nx: grid.nx(), ny: grid.ny(), rect: grid.rect() };
        Self { frame, samples: Samples::Whole(grid) }
    }

    /// Columns `i0..i0 + width` of the rows from `j0` in `frame`, `values` row by row.
    pub(super) fn window(frame: Frame, [i0, j0]: [usize; 2], width: usize, values: Vec<f64>) -> Self {
        Self { frame, samples: Samples::Window { i0, j0, width, values } }
    }

    /// The samples of `frame` at `columns` × `rows`, `values` row by row.
    pub(super) fn sparse(frame: Frame, columns: Vec<usize>, rows: Vec<usize>, values: Vec<f64>) -> Self {
        Self { frame, samples: Samples::Sparse { columns, rows, values } }
    }

    /// The rectangle through the DEM's corner samples.
    pub fn rect(&self) -> Rect {
        self.frame.rect
    }

    /// The height at `p`, bilinear in the cell that holds it (clamped to the DEM): the same
    /// bits as [`Grid::interpolate`] on the whole DEM.
    pub fn eval(&self, p: Point) -> f64 {
        if let Samples::Whole(grid) = &self.samples {
            return grid.interpolate(p);
        }
        let (i, fx) = cell(self.frame.u(p.x), self.frame.nx);
        let (j, fy) = cell(self.frame.v(p.y), self.frame.ny);
        let bottom = self.value(i, j) * (1.0 - fx) + self.value(i + 1, j) * fx;
        let top = self.value(i, j + 1) * (1.0 - fx) + self.value(i + 1, j + 1) * fx;
        bottom * (1.0 - fy) + top * fy
    }

    /// The sample at column `i`, row `j` of the DEM.
    ///
    /// # Panics
    /// When the view does not hold it: a view is made for the points a tile evaluates.
    fn value(&self, i: usize, j: usize) -> f64 {
        match &self.samples {
            Samples::Whole(grid) => grid.value(i, j),
            Samples::Window { i0, j0, width, values } => values[(j - j0) * width + (i - i0)],
            Samples::Sparse { columns, rows, values } => {
                let a = columns.binary_search(&i).expect("a column the view was made for");
                let b = rows.binary_search(&j).expect("a row the view was made for");
                values[b * columns.len() + a]
            }
        }
    }

    /// The DEM's samples inside `rect` at least `clearance` from its sides, as a grid of
    /// their own; `None` when fewer than two a side are, or more than [`MAX_SAMPLES`].
    pub fn samples_inside(&self, rect: Rect, clearance: f64) -> Option<Grid> {
        let range @ [i0, i1, j0, j1] = self.frame.inside(rect, clearance)?;
        if count(range) > MAX_SAMPLES || matches!(self.samples, Samples::Sparse { .. }) {
            return None;
        }
        let values = (j0..=j1).flat_map(|j| (i0..=i1).map(move |i| self.value(i, j))).collect();
        let r = self.frame.rect;
        let x = |i| node_coordinate(i, self.frame.nx, r.x0(), r.x1());
        let y = |j| node_coordinate(j, self.frame.ny, r.y0(), r.y1());
        let domain = Rect::new(x(i0), x(i1), y(j0), y(j1)).ok()?;
        Some(Grid::new(i1 - i0 + 1, j1 - j0 + 1, values).ok()?.with_domain(domain))
    }
}
