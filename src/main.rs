//! The `meshfit` command line: with no arguments (or `serve`) it runs the HTTP service;
//! `meshfit mesh ...` writes one mesh document to stdout, `meshfit solve FILE` one solution.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use meshfit::api::SolveRequest;
use meshfit::config::{Config, RawConfig};
use meshfit::geom::Rect;
use meshfit::jobs::{Limits, SolveSpec};
use meshfit::output::{self, Format, Options, json};
use meshfit::refine::{Criterion, MAX_VERTICES, Method, Params, estimate_error, refine};
use meshfit::result::MeshResult;
use meshfit::source::{Encoding, Expression, GridHints, RawType, Source, decode_grid};
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

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
}

/// Each flag sets the MESHFIT_* variable named in its help; see the README's table.
#[derive(Args, Default)]
struct ServeArgs {
    /// MESHFIT_ADDR: where to listen [default: 0.0.0.0:8080].
    #[arg(long, value_name = "HOST:PORT")]
    addr: Option<String>,
    /// MESHFIT_WORKERS: refinements at once [default: available cores].
    #[arg(long, value_name = "N")]
    workers: Option<String>,
    /// MESHFIT_QUEUE: jobs that may wait for a worker [default: 64].
    #[arg(long, value_name = "N")]
    queue: Option<String>,
    /// MESHFIT_MAX_VERTICES: largest max_vertices per job [default: 2000000].
    #[arg(long, value_name = "N")]
    max_vertices: Option<String>,
    /// MESHFIT_MAX_GRID_POINTS: largest nx*ny [default: 16785409, 4097 x 4097].
    #[arg(long, value_name = "N")]
    max_grid_points: Option<String>,
    /// MESHFIT_MAX_BODY_BYTES: largest request body [default: 268435456].
    #[arg(long, value_name = "BYTES")]
    max_body_bytes: Option<String>,
    /// MESHFIT_MAX_EXPRESSION_LEN: longest expression in characters [default: 4096].
    #[arg(long, value_name = "N")]
    max_expression_len: Option<String>,
    /// MESHFIT_JOB_TIME_LIMIT_MS: longest a job may run [default: 60000].
    #[arg(long, value_name = "MS")]
    job_time_limit_ms: Option<String>,
    /// MESHFIT_MEMORY_BYTES: the memory budget for bodies, jobs and cached meshes [default:
    /// half the machine's or the container's memory].
    #[arg(long, value_name = "BYTES")]
    memory_bytes: Option<String>,
    /// MESHFIT_CACHE_BYTES: memory for finished meshes [default: 1073741824].
    #[arg(long, value_name = "BYTES")]
    cache_bytes: Option<String>,
    /// MESHFIT_CACHE_DIR: also keep finished meshes here, across restarts [default: unset].
    #[arg(long, value_name = "DIR")]
    cache_dir: Option<String>,
    /// MESHFIT_CACHE_DIR_BYTES: disk for those meshes, least recently used deleted first
    /// [default: 10737418240].
    #[arg(long, value_name = "BYTES")]
    cache_dir_bytes: Option<String>,
    /// MESHFIT_SHUTDOWN_GRACE_MS: time running jobs get after SIGTERM [default: 10000].
    #[arg(long, value_name = "MS")]
    shutdown_grace_ms: Option<String>,
    /// MESHFIT_LOG_FORMAT: text or json [default: text].
    #[arg(long, value_name = "FORMAT")]
    log_format: Option<String>,
    /// MESHFIT_MAX_CONNECTIONS: connections served at once [default: the file limit less 256].
    #[arg(long, value_name = "N")]
    max_connections: Option<String>,
    /// MESHFIT_HEADER_TIMEOUT_MS: time to send a request's headers, idle time included
    /// [default: 15000].
    #[arg(long, value_name = "MS")]
    header_timeout_ms: Option<String>,
    /// MESHFIT_BODY_TIMEOUT_MS: longest pause in a request body [default: 15000].
    #[arg(long, value_name = "MS")]
    body_timeout_ms: Option<String>,
    /// MESHFIT_WRITE_TIMEOUT_MS: longest a response waits for its reader [default: 30000].
    #[arg(long, value_name = "MS")]
    write_timeout_ms: Option<String>,
    /// MESHFIT_API_KEYS_FILE: a file of API keys, one per line; with keys, /v1 needs one
    /// [default: unset, the API is open]. Keys are not taken as flags: they would show in
    /// the process list.
    #[arg(long, value_name = "FILE")]
    api_keys_file: Option<String>,
    /// MESHFIT_CORS_ORIGINS: origins whose pages may call the API [default: none].
    #[arg(long, value_name = "ORIGINS")]
    cors_origins: Option<String>,
    /// MESHFIT_CLIENT_SHARE: share of the workers and the queue one client may hold
    /// [default: 0.5].
    #[arg(long, value_name = "FRACTION")]
    client_share: Option<String>,
    /// MESHFIT_REDIS_URL: share results and jobs with other replicas through this Redis
    /// [default: unset, this process serves alone]. A password in it would show in the
    /// process list: give that one as the variable.
    #[arg(long, value_name = "URL")]
    redis_url: Option<String>,
    /// MESHFIT_REDIS_TTL_MS: how long Redis keeps results, records and requests
    /// [default: 86400000].
    #[arg(long, value_name = "MS")]
    redis_ttl_ms: Option<String>,
    /// MESHFIT_REDIS_MAX_BYTES: largest result or request kept in Redis [default: 268435456].
    #[arg(long, value_name = "BYTES")]
    redis_max_bytes: Option<String>,
    /// MESHFIT_REDIS_LEASE_MS: a job's lease, how soon another replica takes over the job of
    /// one that died [default: 10000].
    #[arg(long, value_name = "MS")]
    redis_lease_ms: Option<String>,
}

impl ServeArgs {
    fn config(&self) -> Result<Config> {
        let mut raw = RawConfig::from_env();
        let flags = [
            ("MESHFIT_ADDR", &self.addr),
            ("MESHFIT_WORKERS", &self.workers),
            ("MESHFIT_QUEUE", &self.queue),
            ("MESHFIT_MAX_VERTICES", &self.max_vertices),
            ("MESHFIT_MAX_GRID_POINTS", &self.max_grid_points),
            ("MESHFIT_MAX_BODY_BYTES", &self.max_body_bytes),
            ("MESHFIT_MAX_EXPRESSION_LEN", &self.max_expression_len),
            ("MESHFIT_JOB_TIME_LIMIT_MS", &self.job_time_limit_ms),
            ("MESHFIT_MEMORY_BYTES", &self.memory_bytes),
            ("MESHFIT_CACHE_BYTES", &self.cache_bytes),
            ("MESHFIT_CACHE_DIR", &self.cache_dir),
            ("MESHFIT_CACHE_DIR_BYTES", &self.cache_dir_bytes),
            ("MESHFIT_SHUTDOWN_GRACE_MS", &self.shutdown_grace_ms),
            ("MESHFIT_LOG_FORMAT", &self.log_format),
            ("MESHFIT_MAX_CONNECTIONS", &self.max_connections),
            ("MESHFIT_HEADER_TIMEOUT_MS", &self.header_timeout_ms),
            ("MESHFIT_BODY_TIMEOUT_MS", &self.body_timeout_ms),
            ("MESHFIT_WRITE_TIMEOUT_MS", &self.write_timeout_ms),
            ("MESHFIT_API_KEYS_FILE", &self.api_keys_file),
            ("MESHFIT_CORS_ORIGINS", &self.cors_origins),
            ("MESHFIT_CLIENT_SHARE", &self.client_share),
            ("MESHFIT_REDIS_URL", &self.redis_url),
            ("MESHFIT_REDIS_TTL_MS", &self.redis_ttl_ms),
            ("MESHFIT_REDIS_MAX_BYTES", &self.redis_max_bytes),
            ("MESHFIT_REDIS_LEASE_MS", &self.redis_lease_ms),
        ];
        for (name, value) in flags {
            if let Some(v) = value {
                raw.set(name, v.clone());
            }
        }
        Ok(Config::try_from(raw)?)
    }
}

fn serve(args: &ServeArgs) -> Result<()> {
    let config = args.config()?;
    meshfit::telemetry::init(config.log_format);
    let runtime =
        tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting tokio")?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(config.addr)
            .await
            .with_context(|| format!("cannot listen on {}", config.addr))?;
        tracing::info!(addr = %listener.local_addr()?, workers = config.workers, queue = config.queue, "meshfit listening");
        meshfit::serve(listener, config, shutdown_signal()).await.context("serving")
    })
}

/// Ctrl-C or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = term => {}
    }
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["function", "grid"])))]
struct MeshArgs {
    /// F as a meval expression in x and y, e.g. "sin(x)*cos(y)".
    #[arg(long, value_name = "EXPR")]
    function: Option<String>,
    /// F sampled on a grid, from a file: .npy, 8- or 16-bit greyscale PNG, a colour PNG
    /// elevation tile (give --encoding), TIFF/GeoTIFF, raw little-endian samples (give --nx,
    /// --ny and --dtype), or JSON {"nx", "ny", "values"}. The format is read from the content,
    /// not the name.
    #[arg(long, value_name = "FILE")]
    grid: Option<PathBuf>,
    /// Samples along x of a raw grid file.
    #[arg(long, value_name = "N", requires = "grid")]
    nx: Option<usize>,
    /// Samples along y of a raw grid file.
    #[arg(long, value_name = "N", requires = "grid")]
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
    /// The vertex budget n (at least 4).
    #[arg(long, value_name = "N", default_value_t = 10_000)]
    max_vertices: usize,
    /// recursive (no flips) or semi-recursive (Delaunay flips after each insertion).
    #[arg(long, default_value_t = Method::default())]
    method: Method,
    /// How the worst edge is chosen: error (an edge of the triangle with the largest sampled
    /// |F − F_n|) or variation (the paper's exact algorithm: the largest |zi − zj|).
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
    /// Stop after this many milliseconds.
    #[arg(long, value_name = "MS")]
    time_limit_ms: Option<u64>,
    /// Print only the stats, the E_n estimate and the refinement's time (`elapsed_ms`).
    #[arg(long, conflicts_with_all = ["format", "output"])]
    stats: bool,
    #[command(flatten)]
    output: OutputArgs,
}

fn parse_format(s: &str) -> Result<Format, String> {
    Format::from_name(s).ok_or_else(|| format!("unknown format `{s}`; known formats: {}", Format::names()))
}

/// Where a result goes and how it is written: the flags `mesh` and `solve` share.
#[derive(Args)]
struct OutputArgs {
    /// The output format: json, obj, ply, stl, vtu, msh, glb, svg or png [default: from the
    /// extension of --output, else json].
    #[arg(long, value_name = "FORMAT", value_parser = parse_format)]
    format: Option<Format>,
    /// Write to this file instead of stdout.
    #[arg(long, short, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Factor on z for the 3-D formats a viewer shows to scale (glb).
    #[arg(long, value_name = "FACTOR", default_value_t = 1.0)]
    z_scale: f64,
    /// Width in pixels of a png picture.
    #[arg(long, value_name = "PIXELS", default_value_t = 1024)]
    size: u32,
}

impl OutputArgs {
    /// --format, else the format --output's extension names, else JSON.
    fn format(&self) -> Result<Format> {
        if let Some(f) = self.format {
            return Ok(f);
        }
        let Some(path) = &self.output else { return Ok(Format::Json) };
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        Format::from_name(ext).with_context(|| {
            format!("cannot tell the format of {} from its extension; give --format", path.display())
        })
    }

    /// Checks the flags before any work is done.
    fn check(&self) -> Result<Format> {
        if !(self.z_scale.is_finite()) {
            bail!("--z-scale must be a finite number");
        }
        self.format()
    }

    /// Writes `result` as the flags say.
    fn write(&self, result: MeshResult, format: Format) -> Result<()> {
        let options = Options { id: None, z_scale: self.z_scale, size: self.size };
        let encoding = output::encode(&Arc::new(result), format, &options);
        match &self.output {
            Some(path) => {
                let file = std::fs::File::create(path)
                    .with_context(|| format!("cannot create {}", path.display()))?;
                let mut out = BufWriter::new(file);
                encoding
                    .write_to(&mut out)
                    .and_then(|()| out.flush())
                    .with_context(|| format!("writing {}", path.display()))
            }
            None => to_stdout(|out| {
                encoding.write_to(out)?;
                if format == Format::Json {
                    writeln!(out)?;
                }
                Ok(())
            }),
        }
    }
}

#[derive(Args)]
struct SolveArgs {
    /// The request: a JSON file as POST /v1/solutions takes, or - for stdin.
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// Print only the stats, with the time at the end of each solve (`solve_times_ms`).
    #[arg(long, conflicts_with_all = ["format", "output"])]
    stats: bool,
    #[command(flatten)]
    output: OutputArgs,
}

fn solve(args: &SolveArgs) -> Result<()> {
    let path = &args.file;
    let text = if path.as_os_str() == "-" {
        std::io::read_to_string(std::io::stdin()).context("reading stdin")?
    } else {
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?
    };
    let request: SolveRequest =
        serde_json::from_str(&text).with_context(|| format!("{} is not a valid request", path.display()))?;
    let limits = Limits {
        max_vertices: MAX_VERTICES,
        max_grid_points: usize::MAX,
        max_expression_len: usize::MAX,
        job_time_limit: Duration::MAX,
    };
    let (spec, _) = SolveSpec::from_request(request, &limits)?;
    let format = args.output.check()?;
    let adapted = spec.solve(&mut ())?;
    if args.stats {
        let times: Vec<f64> = adapted.times.iter().map(|t| t.as_secs_f64() * 1e3).collect();
        let result = MeshResult::solution(adapted, spec.physics);
        let doc = serde_json::json!({"stats": result.stats, "solve_times_ms": times});
        return to_stdout(|out| {
            serde_json::to_writer_pretty(&mut *out, &doc)?;
            writeln!(out)
        });
    }
    args.output.write(MeshResult::solution(adapted, spec.physics), format)
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

/// F, and the rectangle its file names (a GeoTIFF's), if any.
fn load_source(args: &MeshArgs) -> Result<(Source, Option<Rect>)> {
    if let Some(text) = &args.function {
        let expr = Expression::parse(text)
            .map_err(|e| anyhow::anyhow!("--function: {e}\n  {text}\n  {:>1$}", "^", e.column))?;
        return Ok((Source::Expression(expr), None));
    }
    let Some(path) = &args.grid else { bail!("give --function or --grid") };
    let bytes = std::fs::read(path).with_context(|| format!("cannot read grid file {}", path.display()))?;
    let hints = GridHints { nx: args.nx, ny: args.ny, dtype: args.dtype, encoding: args.encoding };
    let decoded =
        decode_grid(&bytes, &hints, usize::MAX).with_context(|| format!("grid file {}", path.display()))?;
    Ok((Source::Grid(decoded.grid), decoded.domain))
}

fn mesh(args: &MeshArgs) -> Result<()> {
    let (source, file_domain) = load_source(args)?;
    let rect = args.domain.or(file_domain).unwrap_or_else(|| source.default_domain());
    let source = source.with_domain(rect);
    let mut params = Params::new(args.max_vertices)
        .context("--max-vertices")?
        .with_method(args.method)
        .with_criterion(args.criterion);
    if let Some(t) = args.tolerance {
        params = params.with_tolerance(t).context("--tolerance")?;
    }
    if let Some(degrees) = args.min_angle {
        if args.criterion == Criterion::Variation {
            bail!("--min-angle needs --criterion error: the paper's variation splits only its worst edge");
        }
        params = params.with_min_angle(degrees).context("--min-angle")?;
    }
    if let Some(ms) = args.time_limit_ms {
        params = params.with_time_limit(Duration::from_millis(ms));
    }
    let format = args.output.check()?;
    let result = refine(&source, rect, &params, &mut ())?;
    if args.stats {
        let document = json::StatsDocument {
            stats: &result.stats,
            error: estimate_error(&result.mesh, &source),
            elapsed_ms: result.elapsed.as_secs_f64() * 1e3,
        };
        return to_stdout(|out| {
            json::write_stats(&document, out)?;
            writeln!(out)
        });
    }
    args.output.write(MeshResult::from(result), format)
}

/// Writes a document to stdout through `write` and flushes it. A reader that closes the pipe
/// early (`meshfit mesh … | head`) has read what it wanted: that ends the command quietly.
fn to_stdout(
    write: impl FnOnce(&mut BufWriter<std::io::StdoutLock<'static>>) -> std::io::Result<()>,
) -> Result<()> {
    let mut out = BufWriter::new(std::io::stdout().lock());
    match write(&mut out).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        written => written.context("writing to stdout"),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match &cli.command {
        None => serve(&ServeArgs::default()),
        Some(Command::Serve(args)) => serve(args),
        Some(Command::Mesh(args)) => mesh(args),
        Some(Command::Solve(args)) => solve(args),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
