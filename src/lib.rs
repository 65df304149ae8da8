//! meshfit: piecewise linear approximation of F(x, y) on a rectangle by a triangle mesh,
//! refined by dividing the worst segment.
//!
//! # Layout
//! Data flows one way: `source` says what F is, `refine` builds the mesh by asking `source`
//! for values and `geom` for topology, `output` writes the result.
//!
//! - [`geom`]: points, the rectangle, the half-edge mesh, edge splits and flips, exact
//!   predicates (`robust`) and invariant checks. Depends on nothing else in the crate.
//! - [`source`]: the [`Surface`](source::Surface) trait and its two sources, a `meval`
//!   expression compiled once and a sampled grid with bilinear interpolation.
//! - [`refine`]: the refinement loop, its parameters, the worst-edge queue and the measures
//!   of a finished mesh (V_n, E_n). Depends on `geom` and `source`.
//! - [`output`]: the mesh document (JSON) shared by the command line and the API.
//!
//! ```text
//! output ──▶ refine ──▶ geom
//!              │
//!              └──────▶ source ──▶ geom
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod geom;
pub mod output;
pub mod refine;
pub mod source;
