//! F as a request gives it: an expression or a grid.

use super::expr::Expression;
use super::grid::Grid;
use super::surface::Surface;
use crate::geom::{Point, Rect};

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
