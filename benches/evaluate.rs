//! F_n at many points: point location by bucket grid and walk, on a 10^5-vertex mesh, for
//! points scattered at random and for a raster read row by row.
//!
//! Run with `cargo bench --bench evaluate`; throughput is in points per second.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
#[path = "support/franke.rs"]
mod support;

use meshfit::geom::{Point, Rect};
use meshfit::refine::{Method, Params, refine};
use meshfit::result::RunResult;
use meshfit::result::locate::Locator;
use std::hint::black_box;
use support::{franke, scatter};

fn evaluate(c: &mut Criterion) {
    let mut group = c.benchmark_group("evaluate");
    for method in [Method::SemiRecursive, Method::Recursive] {
        let params = Params::builder(100_000).method(method).build().unwrap();
        let mesh: RunResult = refine(&franke, Rect::unit(), &params, &mut ()).unwrap().into();
        let locator = Locator::new(&mesh);
        let points: Vec<Point> = scatter(1_000_000);
        group.throughput(Throughput::Elements(points.len() as u64));
        group.sample_size(10);
        group.bench_function(format!("{method}/franke/100000/1000000_points"), |b| {
            b.iter(|| points.iter().map(|&p| locator.value(p).unwrap_or(0.0)).sum::<f64>())
        });
        // The batch call the API makes: sorted by bucket first.
        group.bench_function(format!("{method}/franke/100000/1000000_points_batch"), |b| {
            b.iter(|| locator.values(black_box(&points)))
        });
        // The same number of points as a 1000 × 1000 raster, row by row: resampling to an
        // image, where neighbouring queries share buckets and triangles.
        let raster: Vec<Point> = (0..1_000_000u32)
            .map(|k| Point::new(f64::from(k % 1000) / 999.0, f64::from(k / 1000) / 999.0))
            .collect();
        group.bench_function(format!("{method}/franke/100000/1000x1000_raster"), |b| {
            b.iter(|| raster.iter().map(|&p| locator.value(p).unwrap_or(0.0)).sum::<f64>())
        });
        group.bench_function(format!("{method}/franke/100000/index"), |b| {
            b.iter(|| Locator::new(black_box(&mesh)))
        });
    }
    group.finish();
}

criterion_group!(benches, evaluate);
criterion_main!(benches);
