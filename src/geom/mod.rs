//! Planar geometry: points, the rectangle, the triangle mesh and its exact predicates.
//!
//! Pure, synchronous and deterministic: nothing here knows about expressions, threads or I/O.

mod check;
mod constrained;
mod constraints;
mod flip;
mod mesh;
mod point;
pub mod predicates;
pub mod raster;
mod rect;
mod split;

pub use check::InvariantError;
pub use constrained::ConstrainedError;
pub use mesh::{Edge, Mesh, NONE};
pub use point::{Point, Vertex};
pub use rect::{MAX_COORDINATE, MIN_RELATIVE_SIDE, MIN_SIDE, Rect, RectError};
pub use split::Split;
