//! Where F comes from: a parsed expression or a sampled grid, both behind [`Surface`], and the
//! grid files ([`decode_grid`]) a grid is read from.

mod expr;
mod file;
mod grid;

pub use expr::{ExprError, ExprErrorKind, Expression};
pub use file::{
    DecodedGrid, Encoding, GridFileError, GridFileKind, GridHints, RawType, decode_grid, decode_values,
    signed_kind,
};
pub use grid::{BLOCK, Grid, GridError};

use crate::geom::{Point, Rect};

/// A function F(x, y) that refinement samples.
///
/// `eval` may return a non-finite value where F is undefined; the caller turns that into an
/// error naming the point, so a mesh never holds NaN or infinity.
pub trait Surface: Sync {
    /// F at `p`.
    fn eval(&self, p: Point) -> f64;

    /// F at each of `points` into `out` (same length), with the same bits as [`Surface::eval`];
    /// sources that can share work across points (a compiled expression) override it.
    fn eval_many(&self, points: &[Point], out: &mut [f64]) {
        for (p, o) in points.iter().zip(out) {
            *o = self.eval(*p);
        }
    }

    /// The sampled grid behind this surface, if any: error estimation then visits every node.
    fn grid(&self) -> Option<&Grid> {
        None
    }
}

impl<F: Fn(f64, f64) -> f64 + Sync> Surface for F {
    #[inline]
    fn eval(&self, p: Point) -> f64 {
        self(p.x, p.y)
    }
}

/// F as a request describes it: an expression, or a grid with its domain.
#[derive(Debug, Clone)]
pub enum Source {
    /// A `meval` expression in x and y.
    Expression(Expression),
    /// Values on a regular grid, bilinear between nodes.
    Grid(Grid),
}

impl Source {
    /// The rectangle to mesh when the request names none: the unit square for an expression,
    /// the grid's index range [0, nx−1] × [0, ny−1] for a grid.
    pub fn default_domain(&self) -> Rect {
        match self {
            Source::Expression(_) => Rect::unit(),
            Source::Grid(g) => g.default_domain(),
        }
    }
}

impl Source {
    /// The same F on `rect`: a grid's samples are spread over it; an expression is unchanged.
    pub fn with_domain(self, rect: Rect) -> Self {
        match self {
            Source::Grid(g) => Source::Grid(g.with_domain(rect)),
            expression => expression,
        }
    }
}

impl Surface for Source {
    #[inline]
    fn eval(&self, p: Point) -> f64 {
        match self {
            Source::Expression(e) => e.eval(p),
            Source::Grid(g) => g.eval(p),
        }
    }

    fn eval_many(&self, points: &[Point], out: &mut [f64]) {
        match self {
            Source::Expression(e) => e.eval_many(points, out),
            Source::Grid(g) => g.eval_many(points, out),
        }
    }

    fn grid(&self) -> Option<&Grid> {
        match self {
            Source::Expression(_) => None,
            Source::Grid(g) => Some(g),
        }
    }
}
