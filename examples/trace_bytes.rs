//! Bytes a trace takes per vertex at 10^5 vertices, for each method and criterion: the
//! figure in the README. Run with `cargo run --release --example trace_bytes`.

use meshfit::geom::Rect;
use meshfit::refine::trace::Recorder;
use meshfit::refine::{Criterion, Method, Params, refine};
fn main() {
    let f = |x: f64, y: f64| {
        0.75 * (-((9.0 * x - 2.0).powi(2) + (9.0 * y - 2.0).powi(2)) / 4.0).exp() + (3.0 * x).sin() * y
    };
    for criterion in [Criterion::Variation, Criterion::Error] {
        for method in [Method::SemiRecursive, Method::Recursive] {
            let p = Params::builder(100_000).method(method).criterion(criterion).build().unwrap();
            let mut q = ();
            let mut r = Recorder::new(&mut q, &p);
            let run = refine(&f, Rect::unit(), &p, &mut r).unwrap();
            let t = r.finish(run.stats.stop).expect("a replayable method");
            let disk =
                8 * t.worst.len() + 12 * t.splits.len() + 12 * t.estimates.len() + 4 * t.estimate_ends.len();
            println!(
                "{criterion} {method}: {} B/vertex in memory, {} B/vertex on disk, {:.2} estimates/step",
                t.num_bytes() / 100_000,
                disk / 100_000,
                t.estimates.len() as f64 / t.splits.len() as f64
            );
        }
    }
}
