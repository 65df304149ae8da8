//! Refinement speed: Franke's function as a native closure, through meval, and sampled on a
//! 4097 × 4097 grid, at 10^4, 10^5 and 10^6 vertices with both methods; and the error
//! criterion (ids `refine/<method>-error/...`) through meval and on a 1025 × 1025 grid at 10^4
//! and 10^5, on the 4097 × 4097 grid at 10^6, and on a real DEM: the 256 × 256 Terrain-RGB
//! tile of examples/tiles (SRTM-derived heights) at 10^4 and 3·10^4 vertices. `check/delaunay`
//! is the final independent Delaunay check alone, on the semi-recursive mesh of Franke's
//! function at 10^6 vertices. The curvature criterion (ids `refine/<method>-curvature/...`)
//! runs on the native Franke at 10^4, 10^5 and 10^6. `estimate/error` is the final E_n estimate alone (F through
//! meval on every triangle's lattice), on the error criterion's mesh of Franke at 10^5.
//!
//! Run with `cargo bench --bench refine`; pick a subset with a filter, e.g.
//! `cargo bench --bench refine -- semi-recursive/franke_native`.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
#[path = "support/franke.rs"]
mod support;

use meshfit::geom::Rect;
use meshfit::refine::{Method, Params, estimate_error, refine};
use meshfit::source::{Encoding, Expression, Grid, GridHints, Source, Surface, decode_grid};
use std::hint::black_box;
use std::time::Duration;
use support::{FRANKE, franke};

fn franke_grid(n: usize) -> Grid {
    let h = 1.0 / (n - 1) as f64;
    let values = (0..n * n).map(|k| franke((k % n) as f64 * h, (k / n) as f64 * h)).collect();
    Grid::new(n, n, values).unwrap().with_domain(Rect::unit())
}

/// The tile the README's curl line sends, its pixels on the unit square.
fn jacksboro_tile() -> Grid {
    let png = include_bytes!("../examples/tiles/jacksboro-terrain-rgb.png");
    let hints = GridHints { encoding: Some(Encoding::TerrainRgb), ..GridHints::default() };
    decode_grid(png, &hints, 1 << 20).unwrap().grid.with_domain(Rect::unit())
}

fn run<S: Surface + ?Sized>(c: &mut Criterion, name: &str, surface: &S) {
    run_with(c, name, surface, meshfit::refine::Criterion::Variation, &[10_000, 100_000, 1_000_000]);
}

fn run_with<S: Surface + ?Sized>(
    c: &mut Criterion,
    name: &str,
    surface: &S,
    criterion: meshfit::refine::Criterion,
    sizes: &[usize],
) {
    let mut group = c.benchmark_group("refine");
    for method in [Method::Recursive, Method::SemiRecursive] {
        for &n in sizes {
            let params = Params::builder(n).method(method).criterion(criterion).build().unwrap();
            // Ids read refine/<method>/<surface>/<n> for the paper's criterion and
            // refine/<method>-<criterion>/<surface>/<n> for the others.
            let method = match criterion {
                meshfit::refine::Criterion::Variation => method.to_string(),
                other => format!("{method}-{other}"),
            };
            group.throughput(Throughput::Elements(n as u64));
            group.sample_size(if n >= 1_000_000 { 10 } else { 20 });
            group.measurement_time(Duration::from_secs(if n >= 1_000_000 { 15 } else { 5 }));
            group.bench_with_input(BenchmarkId::new(format!("{method}/{name}"), n), &params, |b, params| {
                b.iter(|| black_box(refine(surface, Rect::unit(), params, &mut ()).unwrap().stats.vertices));
            });
        }
    }
    group.finish();
}

/// The check behind `stats.delaunay`, on a mesh built once, and only when the filter picks it.
fn delaunay_check(c: &mut Criterion) {
    let mesh = std::sync::OnceLock::new();
    let mut group = c.benchmark_group("check");
    group.bench_function("delaunay/franke_native/1000000", |b| {
        let mesh = mesh.get_or_init(|| {
            let params = Params::new(1_000_000).unwrap();
            refine(&franke, Rect::unit(), &params, &mut ()).unwrap().mesh
        });
        b.iter(|| black_box(mesh.is_delaunay()));
    });
    group.finish();
}

/// The final E_n estimate behind `stats.error`, on a mesh built once.
fn error_estimate(c: &mut Criterion, meval: &Source) {
    let mesh = refine(meval, Rect::unit(), &Params::new(100_000).unwrap(), &mut ()).unwrap().mesh;
    let mut group = c.benchmark_group("estimate");
    group.throughput(Throughput::Elements(mesh.num_triangles() as u64));
    group.bench_function("error/franke_meval/100000", |b| {
        b.iter(|| black_box(estimate_error(&mesh, meval).max_error))
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    delaunay_check(c);
    let meval = Source::Expression(Expression::parse(FRANKE).unwrap());
    error_estimate(c, &meval);
    run(c, "franke_native", &franke);
    run(c, "franke_meval", &meval);
    let grid4097 = Source::Grid(franke_grid(4097));
    run(c, "franke_grid4097", &grid4097);
    let error = meshfit::refine::Criterion::Error;
    run_with(c, "franke_meval", &meval, error, &[10_000, 100_000]);
    run_with(c, "franke_grid1025", &Source::Grid(franke_grid(1025)), error, &[10_000, 100_000]);
    run_with(c, "franke_grid4097", &grid4097, error, &[1_000_000]);
    run_with(c, "jacksboro_tile256", &Source::Grid(jacksboro_tile()), error, &[10_000, 30_000]);
    let curvature = meshfit::refine::Criterion::Curvature;
    run_with(c, "franke_native", &franke, curvature, &[10_000, 100_000, 1_000_000]);
}

criterion_group!(refine_benches, benches);
criterion_main!(refine_benches);
