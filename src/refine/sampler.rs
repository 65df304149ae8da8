//! F as a refinement samples it: a count of evaluations, and a clear error where F is not
//! finite.

use super::estimator::Field;
use super::outcome::RefineError;
use crate::geom::{Point, Vertex};
use crate::source::Surface;

/// F with a count of evaluations; a non-finite value is an error naming the point.
pub(super) struct Sampler<'s, S: ?Sized> {
    pub(super) surface: &'s S,
    pub(super) evaluations: u64,
    /// The error criterion's samples of a step, kept so that steps do not allocate.
    pub(super) batch: Batch,
}

impl<S: Surface + ?Sized> Sampler<'_, S> {
    #[inline]
    pub(super) fn eval(&mut self, p: Point) -> Result<f64, RefineError> {
        self.evaluations += 1;
        let value = self.surface.eval(p);
        if value.is_finite() { Ok(value) } else { Err(RefineError::NonFinite { point: p, value }) }
    }

    /// F at each point into `out`; the first non-finite value is the error.
    #[inline]
    pub(super) fn eval_many(&mut self, points: &[Point], out: &mut [f64]) -> Result<(), RefineError> {
        self.evaluations += points.len() as u64;
        self.surface.eval_many(points, out);
        match out.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => Err(RefineError::NonFinite { point: points[i], value: out[i] }),
        }
    }
}

impl<S: Surface + ?Sized> Field for Sampler<'_, S> {
    type Error = RefineError;

    #[inline]
    fn midpoint(&mut self, _a: Vertex, _b: Vertex, m: Point) -> Result<f64, RefineError> {
        self.eval(m)
    }

    fn evaluations(&self) -> u64 {
        self.evaluations
    }
}

/// A step's lattice points, sampled as one batch: a compiled expression runs a full batch at
/// about half the cost a point of one triangle's six (`benches/expression.rs`).
#[derive(Debug, Default)]
pub(super) struct Batch {
    pub(super) points: Vec<Point>,
    /// The interpolant at each point.
    pub(super) linear: Vec<f64>,
    /// Where each point's error goes: 0..3 for an edge (half-edge position), 3 inside.
    pub(super) owner: Vec<u8>,
    pub(super) values: Vec<f64>,
    /// How many points each triangle has, in order.
    pub(super) counts: Vec<u8>,
}
