//! Refinement by dividing the worst segment.
//!
//! # Usage
//! [`refine`] takes a [`Surface`](crate::source::Surface), the rectangle, [`Params`] and an [`Observer`], and returns
//! the mesh with its [`Stats`]:
//! ```
//! use meshfit::geom::Rect;
//! use meshfit::refine::{refine, Params, StopReason};
//! let f = |x: f64, y: f64| (x * x + y * y).sqrt();
//! let result = refine(&f, Rect::unit(), &Params::new(500).unwrap(), &mut ()).unwrap();
//! assert_eq!(result.mesh.num_vertices(), 500);
//! assert_eq!(result.stats.stop, StopReason::MaxVertices);
//! assert!(result.stats.delaunay);
//! ```
//!
//! # Algorithm
//! Start from S₄ (the corners, diagonal P1P3). Repeatedly take the worst edge and insert its
//! midpoint M with z = F(M), splitting the one or two triangles beside it. `semi-recursive`
//! then restores the Delaunay property with Lawson flips around M; `recursive` never flips.
//! `data-dependent` (a grid with criterion `error`) is `semi-recursive` until the last
//! insertion, then flips the worst triangles' edges where that lowers the largest error.
//!
//! The criterion says which edge is worst. [`Criterion::Variation`] is the paper's: the
//! largest |zᵢ − zⱼ|, then the longest, then the smallest ids. With [`Criterion::Error`] (the
//! default) every triangle carries a sampled error e(T) = max |F − F_n|, and the worst
//! triangle's worst long edge is bisected (`semi-recursive`) or its longest-edge propagation
//! path is followed (`recursive`, Rivara), which bounds angles from below.
//!
//! # Guarantees
//! - Every triangle is strictly counter-clockwise (exact `orient2d`), and the triangles tile
//!   the rectangle; vertex ids are in insertion order and old vertices never move.
//! - `semi-recursive` meshes pass the exact in-circle test on every interior edge; the
//!   reported `delaunay` flag is an independent check of the final mesh (false for a
//!   `data-dependent` mesh once it flipped for its error).
//! - The same input gives the same mesh bit for bit: one thread, a total order on edges.
//!
//! # Limitations
//! A rounded midpoint of an interior edge can sit a hair off the edge. A split is not made when
//! it would create a non-positive triangle or one smaller than 1e-18 × the rectangle's area,
//! or when the edge is shorter than 1e-9 × the rectangle's diagonal: the edge is *retired*
//! (counted in the stats) and refinement moves on. The floors bound the creep of value-driven
//! splitting toward a point (a cone's tip) or a line (slivers along the boundary), so no run
//! hangs or makes subnormal coordinates.
//!
//! # Stability
//! The order of splits may change between versions of meshfit (the service keys its cache by
//! an engine version); it never changes between two runs of one version.

mod angles;
pub mod asked;
mod bands;
mod curvature_criterion;
mod driver;
mod error_criterion;
mod estimator;
mod floors;
mod history;
mod measures;
mod nodes;
mod observer;
mod outcome;
mod params;
mod run;
mod sampler;
mod sides;
pub mod trace;
mod variation_criterion;
mod worst_edge;
mod worst_triangle;

pub use driver::refine;
pub(crate) use driver::resume;
pub(crate) use estimator::{Estimator, Field};
pub(crate) use floors::Floors;
pub use floors::{ABSOLUTE_FLOOR, AREA_FLOOR, LENGTH_FLOOR, RESOLUTION};
pub use history::Sample;
pub use measures::{ErrorEstimate, dense_max_error, estimate_error, variation};
pub use nodes::SAMPLE_CLEARANCE;
pub use observer::{Observer, PROGRESS_INTERVAL, Progress};
pub use outcome::{RefineError, Refinement, Stats, StopReason};
pub use params::{Criterion, MAX_MIN_ANGLE, MAX_VERTICES, Method, Params, ParamsBuilder, ParamsError};
pub use sides::{Sides, refine_with_sides};
pub use worst_edge::{Candidate, WorstEdgeQueue};

#[cfg(test)]
mod tests;
