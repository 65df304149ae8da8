//! The boundary value problem solver: one assembly and factorisation at 10^5 vertices, the
//! whole adaptive loop on a sharp peak, −Δu = f with u = exp(−1000 r²), and the adaptive loop
//! of a nonlinear magnetostatic problem, where Newton's method solves each mesh several times.
//!
//! Run with `cargo bench --bench solve`; ids are `solve/once/100000`,
//! `solve/adaptive_peak/<vertices>` and `solve/adaptive_electromagnet/20000`. The peak's f is a
//! native closure here; through the API it is a meval expression, which `bench/solve.py` times
//! side by side with scikit-fem. The electromagnet is examples/requests/electromagnet.json (two
//! iron parts with a published B–H curve and a coil), as `meshfit solve` reads it.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use meshfit::api::SolveRequest;
use meshfit::geom::Rect;
use meshfit::refine::{Params, refine};
use meshfit::solve::{Problem, Settings, adapt, solve};
use meshfit::spec::{Limits, SolveSpec};
use std::time::Duration;

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

fn electromagnet(c: &mut Criterion) {
    let request: SolveRequest =
        meshfit::api::from_json(include_bytes!("../examples/requests/electromagnet.json")).unwrap();
    let limits = Limits {
        max_vertices: usize::MAX,
        max_grid_points: usize::MAX,
        max_expression_len: usize::MAX,
        job_time_limit: Duration::MAX,
    };
    let (spec, _) = SolveSpec::from_request(request, &limits).unwrap();
    let mut group = c.benchmark_group("solve");
    group.sample_size(10);
    group.throughput(Throughput::Elements(spec.settings.max_vertices as u64));
    group.bench_function(format!("adaptive_electromagnet/{}", spec.settings.max_vertices), |b| {
        b.iter(|| spec.solve(&mut ()).unwrap().stats.energy)
    });
    group.finish();
}

criterion_group!(benches, once, adaptive, electromagnet);
criterion_main!(benches);
