//! The HTTP API: routes, shared state and the layers around them.
//!
//! - `routes`: [`router`], every route to its handler, and the layers, outside-in;
//! - `state`: [`AppState`], what every handler can reach;
//! - `jobs`, `evaluate`, `materials`, `tiles`, `health`, `page`: the handlers, by resource
//!   (`tiles` holds datasets and their terrain tiles);
//! - `extract`, `negotiate`, `head`, [`access`]: what a request carries, and what it may do;
//! - [`problem`]: every error as an RFC 9457 problem document; `sse`: the event streams;
//! - [`conn`]: the connections themselves, their cap and timeouts.

pub mod access;
mod client;
pub mod conn;
mod evaluate;
mod extract;
mod head;
mod health;
mod jobs;
mod materials;
pub mod negotiate;
mod page;
pub mod problem;
mod routes;
mod sse;
mod state;
mod tiles;

pub use extract::parse_json;
pub use routes::{ROUTES, router};
pub use state::{AppState, Locators};
