//! A `meval` expression in x and y, compiled once into a small stack program and a tree of
//! closures.
//!
//! meval parses (its tokenizer and shunting-yard are public); evaluation runs our own
//! compiled form: variables are slots, functions are resolved to pointers once, and the
//! transcendental functions come from the `libm` crate, a pure-Rust port of musl's libm, so
//! the same expression gives the same bits on every machine (the platform libm may differ in
//! the last ulp). Batches run the stack program, each operation over all their points, with
//! `exp` four lanes at a time ([`lanes`]); one point runs the closures ([`closures`]), which
//! keep values in registers. All do the same operations in the same order. The compiled
//! forms are `Send + Sync`, unlike meval's bound closures.

mod closures;
mod error;
mod expression;
mod hint;
mod lanes;
mod program;
#[cfg(test)]
mod tests;

pub use error::{ExprError, ExprErrorKind};
pub use expression::Expression;
