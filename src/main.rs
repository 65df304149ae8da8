//! The `meshfit` command line: with no arguments (or `serve`) it runs the HTTP service;
//! `meshfit mesh ...` writes one mesh document to stdout, `meshfit solve FILE` one solution.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use meshfit::api::{DomainInput, GridInput, JobRequest, SolveRequest};
use meshfit::config::{Config, RawConfig, SETTINGS, Setting};
use meshfit::geom::Rect;
use meshfit::jobs::{SOLUTION_BYTES_PER_VERTEX, available_memory, cli_mesh_bytes_per_vertex};
use meshfit::output::{self, Format, Options, json};
use meshfit::refine::{Criterion, Method, estimate_error, refine};
use meshfit::result::RunResult;
use meshfit::source::{Encoding, RawType};
use meshfit::spec::{JobSpec, Limits, SolveSpec, SpecError};
use std::io::{BufWriter, Write};
use std::net::SocketAddr;
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
    /// Ask the server at MESHFIT_ADDR (or --addr) for GET /healthz: exit 0 when it answers 200
    /// within 3 s, 1 otherwise. For a container's HEALTHCHECK, which then follows the address.
    Health(HealthArgs),
}

#[derive(Args)]
struct HealthArgs {
    /// The server's address, as MESHFIT_ADDR takes it; a wildcard address (0.0.0.0, [::]) is
    /// asked on loopback [default: MESHFIT_ADDR, else 0.0.0.0:8080].
    #[arg(long, value_name = "HOST:PORT")]
    addr: Option<String>,
}

/// How long `meshfit health` waits for the connection and for the answer, each.
const HEALTH_TIMEOUT: Duration = Duration::from_secs(3);

/// One GET /healthz over a plain socket: the binary carries no HTTP client (reqwest is for
/// tests), and the check needs no more than a status line.
fn health(args: &HealthArgs) -> Result<()> {
    use std::io::Read;
    use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, TcpStream};
    // The address the server takes: from the same settings table, unless --addr names one.
    let mut addr = match &args.addr {
        Some(text) => {
            meshfit::config::listen_addr(text).map_err(|why| anyhow::anyhow!("--addr {text:?}: {why}"))?
        }
        None => Config::try_from(RawConfig::from_env())?.addr,
    };
    if addr.ip().is_unspecified() {
        addr.set_ip(match addr.ip() {
            IpAddr::V4(_) => IpAddr::V4(Ipv4Addr::LOCALHOST),
            IpAddr::V6(_) => IpAddr::V6(Ipv6Addr::LOCALHOST),
        });
    }
    let mut stream = TcpStream::connect_timeout(&addr, HEALTH_TIMEOUT)
        .with_context(|| format!("no server answers at {addr}"))?;
    stream.set_read_timeout(Some(HEALTH_TIMEOUT))?;
    stream.set_write_timeout(Some(HEALTH_TIMEOUT))?;
    write!(stream, "GET /healthz HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n")?;
    let mut head = [0u8; 64];
    let n = stream.read(&mut head).with_context(|| format!("the server at {addr} did not answer"))?;
    let status_line = String::from_utf8_lossy(&head[..n]);
    let status_line = status_line.lines().next().unwrap_or("");
    match status_line.split(' ').nth(1) {
        Some("200") => Ok(()),
        _ => bail!("GET http://{addr}/healthz answered {status_line:?}"),
    }
}

/// `meshfit serve`'s flags: one for each of [`SETTINGS`] that has one, which sets its
/// variable over the environment's.
#[derive(Default)]
struct ServeArgs {
    /// The settings given as flags, with their values.
    given: Vec<(&'static Setting, String)>,
}

impl clap::FromArgMatches for ServeArgs {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let given =
            SETTINGS.iter().filter_map(|s| Some((s, matches.get_one::<String>(s.flag?)?.clone()))).collect();
        Ok(Self { given })
    }

    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        // Settings given again replace their earlier values; the others stay.
        for (setting, value) in Self::from_arg_matches(matches)?.given {
            self.given.retain(|(s, _)| s.name != setting.name);
            self.given.push((setting, value));
        }
        Ok(())
    }
}

impl clap::Args for ServeArgs {
    fn augment_args(command: clap::Command) -> clap::Command {
        SETTINGS.iter().fold(command, |command, s| match s.flag {
            Some(flag) => {
                command.arg(clap::Arg::new(flag).long(flag).value_name(s.value_name).help(s.flag_help()))
            }
            None => command,
        })
    }

    fn augment_args_for_update(command: clap::Command) -> clap::Command {
        Self::augment_args(command)
    }
}

impl ServeArgs {
    fn config(&self) -> Result<Config> {
        let mut raw = RawConfig::from_env();
        for (setting, value) in &self.given {
            raw.set_from_flag(setting, value.clone());
        }
        Ok(Config::try_from(raw)?)
    }
}

fn serve(args: &ServeArgs) -> Result<()> {
    let config = args.config()?;
    meshfit::telemetry::init(&config);
    let runtime =
        tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting tokio")?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(config.addr)
            .await
            .with_context(|| format!("cannot listen on {}", config.addr))?;
        let addr = listener.local_addr()?;
        let url = page_url(addr);
        tracing::info!(
            open = %url,
            %addr,
            workers = config.pool.workers,
            queue = config.pool.queue,
            api_keys = if config.callers.api_keys.is_empty() { "off: the API is open" } else { "on" },
            cache_dir = config.cache.dir.as_ref().map_or("none: memory only".into(), |d| d.display().to_string()),
            memory_budget = %Bytes(config.pool.memory_bytes),
            cache = %Bytes(config.cache.memory_bytes),
            "meshfit listening"
        );
        meshfit::serve(listener, config, shutdown_signal()).await.context("serving")
    })
}

/// The address a person opens for a server listening on `addr`: a wildcard address listens
/// on every interface, loopback included.
fn page_url(addr: SocketAddr) -> String {
    let ip = if addr.ip().is_unspecified() { "localhost".to_owned() } else { addr.ip().to_string() };
    let host = if addr.is_ipv6() && ip != "localhost" { format!("[{ip}]") } else { ip };
    format!("http://{host}:{}/", addr.port())
}

/// Bytes as a person reads them: 11.7 GiB.
struct Bytes(u64);

impl std::fmt::Display for Bytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let units = ["B", "KiB", "MiB", "GiB", "TiB"];
        let mut value = self.0 as f64;
        let mut unit = 0;
        while value >= 1024.0 && unit + 1 < units.len() {
            value /= 1024.0;
            unit += 1;
        }
        if unit == 0 { write!(f, "{} B", self.0) } else { write!(f, "{value:.1} {}", units[unit]) }
    }
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
    /// recursive (no flips), semi-recursive (Delaunay flips after each insertion) or, for a
    /// grid with criterion error, data-dependent (semi-recursive, then flips that lower the
    /// largest error, and so leave Delaunay).
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
    fn write(&self, result: RunResult, format: Format) -> Result<()> {
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
    let request: SolveRequest = meshfit::api::from_json(text.as_bytes())
        .with_context(|| format!("{} is not a valid request", path.display()))?;
    let (spec, _) = SolveSpec::from_request(request, &Limits::NONE)?;
    let format = args.output.check()?;
    check_memory(spec.settings.max_vertices, SOLUTION_BYTES_PER_VERTEX, available_memory())?;
    let adapted = spec.solve(&mut ())?;
    if args.stats {
        let times: Vec<f64> = adapted.times.iter().map(|t| t.as_secs_f64() * 1e3).collect();
        let result = adapted.into_result(spec.physics);
        let doc = serde_json::json!({"stats": result.stats, "solve_times_ms": times});
        return to_stdout(|out| {
            serde_json::to_writer_pretty(&mut *out, &doc)?;
            writeln!(out)
        });
    }
    args.output.write(adapted.into_result(spec.physics), format)
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
            Some(field) => anyhow::Error::new(e.clone()).context(format!("--{}", field.replace('_', "-"))),
            None => e.into(),
        },
    }
}

fn mesh(args: &MeshArgs) -> Result<()> {
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
            stats: &result.stats,
            error: estimate_error(&result.mesh, source),
            elapsed_ms: result.elapsed.as_secs_f64() * 1e3,
        };
        return to_stdout(|out| {
            json::write_stats(&document, out)?;
            writeln!(out)
        });
    }
    args.output.write(RunResult::from(result), format)
}

/// Refuses a run of `vertices` vertices at `per_vertex` peak bytes each when that is more than
/// the `available` memory, before it starts: the kernel would kill it when it got there.
fn check_memory(vertices: usize, per_vertex: u64, available: Option<u64>) -> Result<()> {
    let needed = (vertices as u64).saturating_mul(per_vertex);
    match available {
        Some(available) if needed > available => bail!(
            "max_vertices {vertices}: a run this size needs about {} ({per_vertex} bytes a vertex), more \
             than the {} of memory available; lower the budget",
            Bytes(needed),
            Bytes(available)
        ),
        _ => Ok(()),
    }
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
        Some(Command::Health(args)) => health(args),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
