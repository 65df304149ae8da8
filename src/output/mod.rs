//! Writing a finished refinement out.

pub mod json;
