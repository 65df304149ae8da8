//! What `mesh` and `solve` share: where a result goes and in which format, the memory check
//! before a run, and bytes as a person reads them.

use anyhow::{Context, Result, bail};
use clap::Args;
use meshfit::output::{self, Format, Options};
use meshfit::result::RunResult;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::sync::Arc;

fn parse_format(s: &str) -> Result<Format, String> {
    Format::from_name(s).ok_or_else(|| format!("unknown format `{s}`; known formats: {}", Format::names()))
}

/// Where a result goes and how it is written: the flags `mesh` and `solve` share.
#[derive(Args)]
pub(crate) struct OutputArgs {
    /// The output format: json, obj, ply, stl, vtu, msh, glb, svg or png [default: from the
    /// extension of --output, else json].
    #[arg(long, value_name = "FORMAT", value_parser = parse_format)]
    format: Option<Format>,
    /// Write to this file instead of stdout.
    #[arg(long, short, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Factor on z in the formats with 3-D positions (obj, ply, stl, vtu, glb): a vertical
    /// exaggeration.
    #[arg(long, value_name = "FACTOR")]
    z_scale: Option<f64>,
    /// Width in pixels of a png picture.
    #[arg(long, value_name = "PIXELS")]
    size: Option<u32>,
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
    pub(crate) fn check(&self) -> Result<Format> {
        if self.z_scale.is_some_and(|z| !z.is_finite()) {
            bail!("--z-scale must be a finite number");
        }
        let format = self.format()?;
        // As the API does: an option the format does not take is refused, never ignored.
        if self.z_scale.is_some() && !format.takes_z_scale() {
            bail!(
                "--z-scale does not apply to format {}; it applies to obj, ply, stl, vtu and glb",
                format.name()
            );
        }
        if self.size.is_some() && !format.takes_size() {
            bail!("--size does not apply to format {}; it applies to png", format.name());
        }
        Ok(format)
    }

    /// Writes `result` as the flags say.
    pub(crate) fn write(&self, result: RunResult, format: Format) -> Result<()> {
        let defaults = Options::default();
        let options = Options {
            id: None,
            z_scale: self.z_scale.unwrap_or(defaults.z_scale),
            size: self.size.unwrap_or(defaults.size),
        };
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

/// Refuses a run of `vertices` vertices at `per_vertex` peak bytes each when that is more than
/// the `available` memory, before it starts: the kernel would kill it when it got there.
pub(crate) fn check_memory(vertices: usize, per_vertex: u64, available: Option<u64>) -> Result<()> {
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
pub(crate) fn to_stdout(
    write: impl FnOnce(&mut BufWriter<std::io::StdoutLock<'static>>) -> std::io::Result<()>,
) -> Result<()> {
    let mut out = BufWriter::new(std::io::stdout().lock());
    match write(&mut out).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        written => written.context("writing to stdout"),
    }
}

/// Bytes as a person reads them: 11.7 GiB.
pub(crate) struct Bytes(pub(crate) u64);

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
