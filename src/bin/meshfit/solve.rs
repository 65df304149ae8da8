//! `meshfit solve`: a boundary value problem from a request file, solved as the API would.

use super::output::{OutputArgs, check_memory, to_stdout};
use anyhow::{Context, Result};
use clap::Args;
use meshfit::api::SolveRequest;
use meshfit::jobs::{SOLUTION_BYTES_PER_VERTEX, available_memory};
use meshfit::spec::{Limits, SolveSpec};
use std::io::Write;
use std::path::PathBuf;

#[derive(Args)]
pub(crate) struct SolveArgs {
    /// The request: a JSON file as POST /v1/solutions takes, or - for stdin.
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// Print only the stats, with the time at the end of each solve (`solve_times_ms`).
    #[arg(long, conflicts_with_all = ["format", "output"])]
    stats: bool,
    #[command(flatten)]
    output: OutputArgs,
}

pub(crate) fn solve(args: &SolveArgs) -> Result<()> {
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
        let result = spec.result(adapted);
        let doc = serde_json::json!({"stats": result.stats, "solve_times_ms": times});
        return to_stdout(|out| {
            serde_json::to_writer_pretty(&mut *out, &doc)?;
            writeln!(out)
        });
    }
    args.output.write(spec.result(adapted), format)
}
