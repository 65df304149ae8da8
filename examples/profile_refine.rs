//! One refinement of Franke's function, for profilers:
//! `cargo run --release --example profile_refine -- semi-recursive 100000 [variation|error] [native|meval]`
//! (`valgrind --tool=cachegrind` or `perf record` on the binary give repeatable counts).

use meshfit::geom::Rect;
use meshfit::refine::{Criterion, Method, Params, refine};
use meshfit::source::Expression;

const FRANKE: &str = "0.75*exp(-((9*x-2)^2 + (9*y-2)^2)/4) + 0.75*exp(-((9*x+1)^2)/49 - (9*y+1)/10) \
                      + 0.5*exp(-((9*x-7)^2 + (9*y-3)^2)/4) - 0.2*exp(-((9*x-4)^2) - (9*y-7)^2)";

fn franke(x: f64, y: f64) -> f64 {
    let (a, b) = (9.0 * x, 9.0 * y);
    0.75 * (-((a - 2.0).powi(2) + (b - 2.0).powi(2)) / 4.0).exp()
        + 0.75 * (-(a + 1.0).powi(2) / 49.0 - (b + 1.0) / 10.0).exp()
        + 0.5 * (-((a - 7.0).powi(2) + (b - 3.0).powi(2)) / 4.0).exp()
        - 0.2 * (-(a - 4.0).powi(2) - (b - 7.0).powi(2)).exp()
}

fn main() {
    let mut args = std::env::args().skip(1);
    let method: Method = args.next().as_deref().unwrap_or("semi-recursive").parse().expect("a method");
    let n: usize = args.next().as_deref().unwrap_or("100000").parse().expect("a vertex count");
    let criterion: Criterion = args.next().as_deref().unwrap_or("variation").parse().expect("a criterion");
    let params =
        Params::new(n).expect("a budget of at least 4").with_method(method).with_criterion(criterion);
    let result = match args.next().as_deref().unwrap_or("native") {
        "meval" => refine(&Expression::parse(FRANKE).expect("Franke parses"), Rect::unit(), &params, &mut ()),
        _ => refine(&franke, Rect::unit(), &params, &mut ()),
    }
    .expect("Franke is finite");
    println!("{}", serde_json::to_string(&result.stats).expect("stats serialize"));
}
