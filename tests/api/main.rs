//! The HTTP API, tested through a real server on a loopback port with reqwest.
//! One binary for every API test: each file under tests/ would otherwise link separately.

mod access;
mod cache;
mod clients;
mod connections;
mod devices;
mod errors;
mod events;
mod helpers;
mod jobs;
mod page;
mod quickstart;
mod results;
mod service;
mod solutions;
mod tiles;
mod uploads;
