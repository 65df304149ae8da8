//! Results as bytes: each format a client can ask for, encoded from a [`RunResult`](crate::result::RunResult).
//!
//! An encoder does not write the whole file at once. It returns an [`Encoded`]: a list of
//! parts, each either fixed bytes (a header) or rows made on demand (one vertex, one triangle).
//! [`Encoded::write_to`] writes it to a file or stdout; [`Encoded::into_chunks`] makes it
//! piece by piece for an HTTP body, so a client reading a 10^6-vertex mesh costs one chunk of
//! memory beyond the shared result, however slowly it reads.

pub mod colour;
mod contour;
mod encoded;
mod format;
mod glb;
pub mod json;
mod msh;
mod obj;
mod options;
mod picture;
mod ply;
pub mod png;
mod stl;
pub mod svg;
mod vtu;

pub use encoded::{Chunks, Encoded, Part};
pub use format::{Format, encode};
pub use options::Options;
