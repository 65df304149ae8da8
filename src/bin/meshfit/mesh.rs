//! `meshfit mesh`: a mesh of F, checked by the same spec the API uses (without the server's
//! limits), written in any format.

use super::output::{OutputArgs, check_memory, to_stdout};
use anyhow::{Context, Result};
use clap::Args;
use meshfit::api::{DomainInput, GridInput, JobRequest};
use meshfit::geom::Rect;
use meshfit::jobs::{available_memory, cli_mesh_bytes_per_vertex};
use meshfit::output::json;
use meshfit::refine::{Criterion, Method, estimate_error, refine};
use meshfit::result::RunResult;
use meshfit::source::{Encoding, RawType};
use meshfit::spec::{JobSpec, Limits, SpecError};
use std::io::Write;
use std::path::PathBuf;

#[derive(Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["function", "grid"])))]
pub(crate) struct MeshArgs {
    /// F as a meval expression in x and y, e.g. "sin(x)*cos(y)".
    #[arg(long, value_name = "EXPR")]
    function: Option<String>,
    /// F sampled on a grid, from a file: .npy, 8- or 16-bit greyscale PNG, a colour PNG
    /// elevation tile (give --encoding), TIFF/GeoTIFF, raw little-endian samples (give --nx,
    /// --ny and --dtype), or JSON {"nx", "ny", "values"}. The format is read from the content,
    /// not the name. `-` reads it from stdin.
    #[arg(long, value_name = "FILE")]
    grid: Option<PathBuf>,
    /// Samples along x of a raw grid file.
    #[arg(long, value_name = "N", requires = "grid", value_parser = parse_count::<usize>)]
    nx: Option<usize>,
    /// Samples along y of a raw grid file.
    #[arg(long, value_name = "N", requires = "grid", value_parser = parse_count::<usize>)]
    ny: Option<usize>,
    /// Sample type of a raw grid file: f32 or f64.
    #[arg(long, value_name = "TYPE", requires = "grid", value_parser = parse_dtype)]
    dtype: Option<RawType>,
    /// How a colour PNG tile encodes heights: terrain-rgb (−10000 + (R·65536 + G·256 + B)·0.1)
    /// or terrarium (R·256 + G + B/256 − 32768).
    #[arg(long, value_name = "ENCODING", requires = "grid", value_parser = parse_encoding)]
    encoding: Option<Encoding>,
    /// The rectangle a,b,c,d = [a,b]×[c,d]; default [0,1]² for a function, a GeoTIFF's own
    /// rectangle, else [0,nx−1]×[0,ny−1] for a grid. Negative bounds may lead: -3,3,-3,3.
    #[arg(long, value_name = "a,b,c,d", value_parser = parse_domain, allow_hyphen_values = true)]
    domain: Option<Rect>,
    /// The vertex budget n (at least 4); 1e4 is 10000, as in a request.
    #[arg(long, value_name = "N", default_value_t = 10_000, value_parser = parse_count::<usize>)]
    max_vertices: usize,
    /// recursive (no flips), semi-recursive (Delaunay flips after each insertion) or, for a
    /// grid with criterion error, data-dependent (semi-recursive, then flips that lower the
    /// largest error, and so leave Delaunay).
    #[arg(long, default_value_t = Method::default())]
    method: Method,
    /// How the worst edge is chosen: error (an edge of the triangle with the largest sampled
    /// |F − F_n|), variation (the paper's exact algorithm: the largest |zi − zj|) or
    /// curvature (one evaluation a vertex: the edge whose midpoint the vertices' gradients say
    /// is worst interpolated).
    #[arg(long, default_value_t = Criterion::default())]
    criterion: Criterion,
    /// Stop once the worst criterion value is at most T: the largest sampled triangle error
    /// for error, the largest |zi − zj| for variation.
    #[arg(long, value_name = "T")]
    tolerance: Option<f64>,
    /// Criterion error: repair every triangle whose smallest angle is below DEG degrees (at
    /// most 30) before any error-driven split.
    #[arg(long, value_name = "DEG")]
    min_angle: Option<f64>,
    /// Criterion curvature: never split an edge shorter than twice LEN.
    #[arg(long, value_name = "LEN")]
    min_size: Option<f64>,
    /// Criterion curvature: split every edge longer than LEN first.
    #[arg(long, value_name = "LEN")]
    max_size: Option<f64>,
    /// Stop after this many milliseconds.
    #[arg(long, value_name = "MS", value_parser = parse_count::<u64>)]
    time_limit_ms: Option<u64>,
    /// Print only the stats, the E_n estimate and the refinement's time (`elapsed_ms`).
    #[arg(long, conflicts_with_all = ["format", "output"])]
    stats: bool,
    #[command(flatten)]
    output: OutputArgs,
}

/// A count as a request's JSON reads one: 10000, 1e4 and 10000.0 alike.
fn parse_count<T: TryFrom<u64>>(s: &str) -> Result<T, String> {
    meshfit::api::parse_count(s)
        .and_then(|n| T::try_from(n).ok())
        .ok_or_else(|| format!("`{s}` is not a whole number (such as 10000 or 1e4)"))
}

fn parse_domain(s: &str) -> Result<Rect, String> {
    let bounds: Vec<f64> = s
        .split(',')
        .map(|b| b.trim().parse::<f64>().map_err(|_| format!("`{}` is not a number", b.trim())))
        .collect::<Result<_, _>>()?;
    let [a, b, c, d] = bounds[..] else {
        return Err(format!("expected four numbers a,b,c,d, got {}", bounds.len()));
    };
    Rect::new(a, b, c, d).map_err(|e| e.to_string())
}

fn parse_dtype(s: &str) -> Result<RawType, String> {
    RawType::from_name(s).ok_or_else(|| format!("`{s}` is not a sample type; use f32 or f64"))
}

fn parse_encoding(s: &str) -> Result<Encoding, String> {
    Encoding::from_name(s)
        .ok_or_else(|| format!("`{s}` is not a tile encoding; use terrain-rgb or terrarium"))
}

/// The request `args` make, with the grid file's bytes if they name one: the same request the
/// API would take, so the command line checks it by the same rules.
fn mesh_request(args: &MeshArgs) -> Result<(JobRequest<'static>, Option<Vec<u8>>)> {
    let file = match &args.grid {
        Some(path) if path.as_os_str() == "-" => {
            let mut bytes = Vec::new();
            std::io::Read::read_to_end(&mut std::io::stdin(), &mut bytes)
                .context("reading the grid from stdin")?;
            Some(bytes)
        }
        Some(path) => {
            Some(std::fs::read(path).with_context(|| format!("cannot read grid file {}", path.display()))?)
        }
        None => None,
    };
    let grid = args.grid.as_ref().map(|_| GridInput {
        nx: args.nx.map(|n| n as u64),
        ny: args.ny.map(|n| n as u64),
        values: None,
        dtype: args.dtype,
        encoding: args.encoding,
    });
    let request = JobRequest {
        function: args.function.clone(),
        grid,
        domain: args.domain.map(|r| DomainInput { x: vec![r.x0(), r.x1()], y: vec![r.y0(), r.y1()] }),
        max_vertices: Some(args.max_vertices as u64),
        tolerance: args.tolerance,
        method: Some(args.method),
        criterion: Some(args.criterion),
        min_angle: args.min_angle,
        min_size: args.min_size,
        max_size: args.max_size,
        time_limit_ms: args.time_limit_ms,
        quality: None,
    };
    Ok((request, file))
}

/// A request's error as the command line names it: by its flag, with a caret under the column
/// of a bad expression.
fn flag_error(e: SpecError, args: &MeshArgs) -> anyhow::Error {
    match (&e, &args.function) {
        (SpecError::Expression(x), Some(text)) => {
            anyhow::anyhow!("--function: {x}\n  {text}\n  {:>1$}", "^", x.column)
        }
        _ => match e.field() {
            // The message names the request's field ("grid: …"); the flag replaces it.
            Some(field) => {
                let message = e.to_string();
                let message = message.strip_prefix(&format!("{field}: ")).unwrap_or(&message);
                anyhow::anyhow!("--{}: {message}", field.replace('_', "-"))
            }
            None => e.into(),
        },
    }
}

pub(crate) fn mesh(args: &MeshArgs) -> Result<()> {
    let (request, file) = mesh_request(args)?;
    let spec = match &file {
        Some(bytes) => JobSpec::from_upload(request, bytes, &Limits::NONE),
        None => JobSpec::from_request(request, &Limits::NONE),
    }
    .map_err(|e| flag_error(e, args))?;
    let mesh = spec.mesh().expect("a mesh request makes a mesh spec");
    let (source, rect, params) = (&*mesh.source, mesh.domain, &mesh.params);
    let format = args.output.check()?;
    check_memory(params.max_vertices(), cli_mesh_bytes_per_vertex(args.criterion), available_memory())?;
    let result = refine(source, rect, params, &mut ())?;
    if args.stats {
        let document = json::StatsDocument {
            stats: &result.stats.clone().into(),
            error: estimate_error(&result.mesh, source).into(),
            elapsed_ms: result.elapsed.as_secs_f64() * 1e3,
        };
        return to_stdout(|out| {
            json::write_stats(&document, out)?;
            writeln!(out)
        });
    }
    args.output.write(RunResult::from(result), format)
}
