//! One refinement of Franke's function, for profilers:
//! `cargo run --release --example profile_refine -- semi-recursive 100000 [variation|error] [native|meval]`
//! (`valgrind --tool=cachegrind` or `perf record` on the binary give repeatable counts).

#[path = "../benches/support/franke.rs"]
mod support;

use meshfit::geom::Rect;
use meshfit::refine::{Criterion, Method, Params, refine};
use meshfit::source::Expression;
use support::{FRANKE, franke};

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
