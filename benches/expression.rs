//! Evaluating F: Franke's function compiled from its meval text, one point at a time (what the
//! `variation` criterion asks for each new vertex) and in batches (what the error criterion's
//! samples use), against the same function as native Rust, with std's `exp` and with `libm`'s
//! (the portable one the compiled expression calls, so results agree on every machine); and
//! batches of 3 to 12 points (one triangle's samples) and of 30 (about what one step of the
//! error criterion asks for).
//!
//! Run with `cargo bench --bench expression`; throughput is in points per second.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
#[path = "support/franke.rs"]
mod support;

use meshfit::geom::Point;
use meshfit::source::{Expression, Surface};
use std::hint::black_box;
use support::{FRANKE, franke, scatter};

/// Franke's function with `libm::exp`, one call a point: the same bits as the compiled
/// expression, whose batches run the same exp over four lanes at a time.
fn franke_libm(x: f64, y: f64) -> f64 {
    let (a, b) = (9.0 * x, 9.0 * y);
    0.75 * libm::exp(-((a - 2.0).powi(2) + (b - 2.0).powi(2)) / 4.0)
        + 0.75 * libm::exp(-(a + 1.0).powi(2) / 49.0 - (b + 1.0) / 10.0)
        + 0.5 * libm::exp(-((a - 7.0).powi(2) + (b - 3.0).powi(2)) / 4.0)
        - 0.2 * libm::exp(-(a - 4.0).powi(2) - (b - 7.0).powi(2))
}

fn expression(c: &mut Criterion) {
    let compiled = Expression::parse(FRANKE).unwrap();
    let points: Vec<Point> = scatter(4096);
    let mut out = vec![0.0; points.len()];
    let mut group = c.benchmark_group("expression/franke");
    group.throughput(Throughput::Elements(points.len() as u64));
    group.bench_function("native_std_exp", |b| {
        b.iter(|| black_box(&points).iter().map(|p| franke(p.x, p.y)).sum::<f64>())
    });
    group.bench_function("native_libm_exp", |b| {
        b.iter(|| black_box(&points).iter().map(|p| franke_libm(p.x, p.y)).sum::<f64>())
    });
    group.bench_function("compiled_one_by_one", |b| {
        b.iter(|| black_box(&points).iter().map(|&p| compiled.eval(p)).sum::<f64>())
    });
    group.bench_function("compiled_batch", |b| {
        b.iter(|| {
            compiled.eval_many(black_box(&points), &mut out);
            out[0]
        })
    });
    for size in [3, 6, 9, 12, 30] {
        group.bench_function(format!("compiled_batches_of_{size}"), |b| {
            b.iter(|| {
                for (p, o) in black_box(&points).chunks(size).zip(out.chunks_mut(size)) {
                    compiled.eval_many(p, o);
                }
                out[0]
            })
        });
    }
    group.finish();
}

criterion_group!(benches, expression);
criterion_main!(benches);
