//! The boundary value problem solver: one assembly and factorisation at 10^5 vertices, and
//! the whole adaptive loop on a sharp peak, −Δu = f with u = exp(−1000 r²).
//!
//! Run with `cargo bench --bench solve`; ids are `solve/once/100000` and
//! `solve/adaptive_peak/<vertices>`. The peak's f is a native closure here; through the API
//! it is a meval expression, which `bench/solve.py` times side by side with scikit-fem.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use meshfit::geom::Rect;
use meshfit::refine::{Params, refine};
use meshfit::solve::{Problem, Settings, adapt, solve};

fn peak(x: f64, y: f64) -> f64 {
    (-1000.0 * ((x - 0.5).powi(2) + (y - 0.5).powi(2))).exp()
}

fn peak_load(x: f64, y: f64) -> f64 {
    peak(x, y) * (4000.0 - 4e6 * ((x - 0.5).powi(2) + (y - 0.5).powi(2)))
}

fn problem() -> Problem<'static> {
    Problem::new(Rect::unit()).with_f(peak_load).with_g(peak)
}

fn once(c: &mut Criterion) {
    // A graded mesh of the peak from the mesh engine, 10^5 vertices.
    let mesh = refine(&peak, Rect::unit(), &Params::new(100_000).unwrap(), &mut ()).unwrap().mesh;
    let triangles: Vec<[u32; 3]> = mesh.triangles().collect();
    let problem = problem();
    let mut group = c.benchmark_group("solve");
    group.sample_size(10);
    group.throughput(Throughput::Elements(mesh.num_vertices() as u64));
    group.bench_function("once/100000", |b| {
        b.iter(|| solve(&problem, mesh.vertices(), &triangles).unwrap().energy)
    });
    group.finish();
}

fn adaptive(c: &mut Criterion) {
    let problem = problem();
    let mut group = c.benchmark_group("solve");
    group.sample_size(10);
    for n in [10_000, 100_000] {
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(format!("adaptive_peak/{n}"), |b| {
            b.iter(|| adapt(&problem, None, &Settings::new(n), &mut ()).unwrap().stats.energy)
        });
    }
    group.finish();
}

criterion_group!(benches, once, adaptive);
criterion_main!(benches);
