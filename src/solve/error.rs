//! Why a problem could not be solved.

use crate::geom::ConstrainedError;
use faer::sparse::FaerError;

/// Why a problem could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// k is zero, negative or not finite at a quadrature point.
    #[error("k = {value} at ({x}, {y}); k must be finite and positive")]
    InvalidK {
        /// Abscissa of the quadrature point.
        x: f64,
        /// Ordinate of the quadrature point.
        y: f64,
        /// The value found.
        value: f64,
        /// The triangle's index (for library callers; messages name the point).
        triangle: usize,
    },
    /// f is not finite at a quadrature point.
    #[error("f = {value} at ({x}, {y}) is not finite")]
    NonFiniteF {
        /// Abscissa of the quadrature point.
        x: f64,
        /// Ordinate of the quadrature point.
        y: f64,
        /// The value found.
        value: f64,
        /// The triangle's index.
        triangle: usize,
    },
    /// g is not finite at a boundary vertex.
    #[error("g = {value} at boundary point ({x}, {y}) is not finite")]
    NonFiniteG {
        /// Abscissa of the vertex.
        x: f64,
        /// Ordinate of the vertex.
        y: f64,
        /// The value found.
        value: f64,
        /// The vertex's index.
        vertex: usize,
    },
    /// The error estimate of a triangle overflows f64: k, f or the solution is too large.
    #[error(
        "the error estimate near ({x}, {y}) overflows: k, f or the \
         solution is too large for 64-bit floats; scale the problem"
    )]
    Overflow {
        /// Abscissa of the triangle's centroid.
        x: f64,
        /// Ordinate of the triangle's centroid.
        y: f64,
        /// The triangle's index.
        triangle: usize,
    },
    /// A triangle is not counter-clockwise with positive area.
    #[error("triangle {triangle} has signed area {area}; triangles must be counter-clockwise")]
    DegenerateTriangle {
        /// The triangle's index.
        triangle: usize,
        /// Its signed area.
        area: f64,
    },
    /// The stiffness matrix is not numerically positive definite (for instance an interior
    /// vertex that no triangle uses).
    #[error("the stiffness matrix is not positive definite (pivot {pivot} of {unknowns})")]
    NotPositiveDefinite {
        /// The failing pivot, in the solver's (permuted) order.
        pivot: usize,
        /// The number of unknowns.
        unknowns: usize,
    },
    /// The sparse solver could not allocate or index the factor.
    #[error("the sparse factorisation failed: {0}")]
    Factorisation(FaerError),
    /// The regions' sides do not make a mesh.
    #[error(transparent)]
    Regions(#[from] ConstrainedError),
    /// A vertex on a periodic side has no vertex at the matching point of the other side.
    #[error("the vertex ({x}, {y}) on a periodic side has no partner on the opposite side")]
    Unmatched {
        /// Abscissa.
        x: f64,
        /// Ordinate.
        y: f64,
    },
}
