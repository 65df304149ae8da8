//! [`Surface`]: a function F(x, y) as refinement samples it.

use super::grid::Grid;
use crate::geom::Point;

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

impl Surface for Grid {
    #[inline]
    fn eval(&self, p: Point) -> f64 {
        self.interpolate(p)
    }

    fn grid(&self) -> Option<&Grid> {
        Some(self)
    }
}
