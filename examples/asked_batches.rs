//! Points a client job asks for beyond its mesh's own, by batch size: a batch guesses ahead
//! with stand-ins, and a guess the told values overturn goes unused. The table in docs/api.md.
//! Run with `cargo run --release --example asked_batches`.

use meshfit::geom::Rect;
use meshfit::refine::asked::{Next, Told, Values, next};
use meshfit::refine::{Criterion, Params};

/// A function by name.
type Named = (&'static str, fn(f64, f64) -> f64);

fn main() {
    let functions: [Named; 3] = [
        ("sin(3x)·y + xy", |x, y| (3.0 * x).sin() * y + x * y),
        ("exp(−50r²) at (0.3, 0.6)", |x, y| (-50.0 * ((x - 0.3).powi(2) + (y - 0.6).powi(2))).exp()),
        ("Franke's two peaks", |x, y| {
            0.75 * (-((9.0 * x - 2.0).powi(2) + (9.0 * y - 2.0).powi(2)) / 4.0).exp()
                + 0.5 * (-((9.0 * x - 7.0).powi(2) + (9.0 * y - 3.0).powi(2)) / 4.0).exp()
        }),
    ];
    println!(
        "| F on the unit square | criterion | vertices | batch 1 | 4 | 16 | 64 |\n|---|---|---|---|---|---|---|"
    );
    for (name, f) in functions {
        for (criterion, vertices) in
            [Criterion::Curvature, Criterion::Variation].into_iter().flat_map(|c| [(c, 1000), (c, 5000)])
        {
            let params = Params::builder(vertices).criterion(criterion).build().unwrap();
            let unused: Vec<String> = [1, 4, 16, 64]
                .into_iter()
                .map(|batch| {
                    let mut values = Values::new();
                    loop {
                        match next(Rect::unit(), &params, &values, batch).unwrap() {
                            Next::Ask(points) => {
                                points.into_iter().for_each(|p| values.tell(p, Told::Value(f(p.x, p.y))))
                            }
                            Next::Done(_, unused) => {
                                break format!("{unused} ({:.0}%)", 100.0 * unused as f64 / vertices as f64);
                            }
                        }
                    }
                })
                .collect();
            println!("| {name} | {criterion} | {vertices} | {} |", unused.join(" | "));
        }
    }
}
