//! One refinement of Franke's function, for profilers:
//! `cargo run --release --example profile_refine -- semi-recursive 100000 [variation|error] [native|meval|grid<N>]`
//! (`grid4097`: Franke sampled on a 4097 × 4097 grid over [0,1]²; `file:DEM.npy`, any grid file,
//! its domain in grid units; `PROFILE_REPEAT=N` runs it N times, for a short run's profile)
//! (`valgrind --tool=cachegrind` or `perf record` on the binary give repeatable counts).

#[path = "../benches/support/franke.rs"]
mod support;

use meshfit::geom::Rect;
use meshfit::refine::{Criterion, Method, Params, refine};
use meshfit::source::{Expression, Grid, GridHints, decode_grid};
use support::{FRANKE, franke};

fn main() {
    let mut args = std::env::args().skip(1);
    let method: Method = args.next().as_deref().unwrap_or("semi-recursive").parse().expect("a method");
    let n: usize = args.next().as_deref().unwrap_or("100000").parse().expect("a vertex count");
    let criterion: Criterion = args.next().as_deref().unwrap_or("variation").parse().expect("a criterion");
    let params =
        Params::builder(n).method(method).criterion(criterion).build().expect("a budget of at least 4");
    let surface = args.next().unwrap_or_else(|| "native".into());
    let repeat: usize = std::env::var("PROFILE_REPEAT").map_or(1, |n| n.parse().expect("a repeat count"));
    for _ in 1..repeat {
        run(&surface, &params);
    }
    let result = run(&surface, &params);
    let stats = meshfit::result::MeshStats::from(result.stats);
    println!("{}", serde_json::to_string(&stats).expect("stats serialize"));
}

fn run(surface: &str, params: &Params) -> meshfit::refine::Refinement {
    match surface {
        file if file.starts_with("file:") => {
            let bytes = std::fs::read(&file[5..]).expect("a readable grid file");
            let grid = decode_grid(&bytes, &GridHints::default(), usize::MAX).expect("a grid file").grid;
            refine(&grid, grid.rect(), params, &mut ())
        }
        "meval" => refine(&Expression::parse(FRANKE).expect("Franke parses"), Rect::unit(), params, &mut ()),
        grid if grid.starts_with("grid") => {
            let n: usize = grid[4..].parse().expect("grid<N>, e.g. grid4097");
            let h = 1.0 / (n - 1) as f64;
            let values = (0..n * n).map(|k| franke((k % n) as f64 * h, (k / n) as f64 * h)).collect();
            let grid = Grid::new(n, n, values).expect("a valid grid").with_domain(Rect::unit());
            refine(&grid, Rect::unit(), params, &mut ())
        }
        _ => refine(&franke, Rect::unit(), params, &mut ()),
    }
    .expect("F is finite")
}
