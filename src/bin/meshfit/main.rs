//! The `meshfit` command line: with no arguments (or `serve`) it runs the HTTP service;
//! `meshfit mesh ...` writes one mesh document to stdout, `meshfit solve FILE` one solution,
//! `meshfit tiles DEM --out DIR` a terrain pyramid, `meshfit health` asks a running server. The library does the work; each command here reads
//! its flags, calls it, and says what went wrong.

mod health;
mod mesh;
mod output;
mod serve;
mod solve;
mod tiles;

use clap::{Parser, Subcommand};
use health::HealthArgs;
use mesh::MeshArgs;
use serve::ServeArgs;
use solve::SolveArgs;
use std::process::ExitCode;
use tiles::TilesArgs;

#[derive(Parser)]
#[command(version, about = "Piecewise linear approximation of F(x, y) by dividing the worst segment")]
struct Cli {
    /// Without a command, `meshfit` serves the HTTP API with its defaults.
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Serve the HTTP API (the default). Flags override MESHFIT_* variables.
    Serve(Box<ServeArgs>),
    /// Refine a mesh for F and write it to stdout or --output: JSON by default, or any --format.
    Mesh(MeshArgs),
    /// Solve a boundary value problem on an adaptive mesh: FILE holds the JSON body of
    /// POST /v1/solutions ("-" reads stdin); the solution document goes to stdout.
    Solve(SolveArgs),
    /// Write a DEM's terrain tiles for web maps: layer.json and every z/x/y.terrain
    /// (quantized-mesh-1.0), crack-free, each within its level's error. DEM is a GeoTIFF in
    /// EPSG:4326.
    Tiles(TilesArgs),
    /// Ask the server at MESHFIT_ADDR (or --addr) for GET /healthz: exit 0 when it answers 200
    /// within 3 s, 1 otherwise. For a container's HEALTHCHECK, which then follows the address.
    Health(HealthArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match &cli.command {
        None => serve::serve(&ServeArgs::default()),
        Some(Command::Serve(args)) => serve::serve(args),
        Some(Command::Mesh(args)) => mesh::mesh(args),
        Some(Command::Solve(args)) => solve::solve(args),
        Some(Command::Tiles(args)) => tiles::tiles(args),
        Some(Command::Health(args)) => health::health(args),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
