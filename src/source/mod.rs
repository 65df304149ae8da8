//! Where F comes from: a parsed expression or a sampled grid, both behind [`Surface`], and the
//! grid files ([`decode_grid`]) a grid is read from.

mod expr;
mod file;
mod function;
mod grid;
mod surface;

pub use expr::{ExprError, ExprErrorKind, Expression};
pub use file::{
    Crs, DecodedGrid, Encoding, GridFileError, GridFileKind, GridHints, RawType, decode_grid, decode_values,
    signed_kind,
};
pub use function::Source;
pub use grid::{BLOCK, Grid, GridError, node_coordinate};
pub use surface::Surface;
