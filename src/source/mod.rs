//! Where F comes from: a parsed expression or a sampled grid, both behind [`Surface`], and the
//! grid files ([`decode_grid`]) a grid is read from.

mod expr;
mod file;
mod function;
mod grid;
mod surface;

pub use expr::{ExprError, ExprErrorKind, Expression};
pub use file::{
    Block, BlockReader, Crs, DecodedGrid, Encoding, GridFileError, GridFileKind, GridHints, RawType,
    TiffBlocks, decode_grid, decode_values, fill_holes, signed_kind,
};
pub use function::Source;
pub(crate) use grid::cell;
pub use grid::{BLOCK, Grid, GridError, grid_coordinate, node_coordinate};
pub use surface::Surface;
