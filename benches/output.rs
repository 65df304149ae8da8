//! Writing a 10^5-vertex result in every format: the bytes a response streams, made into a
//! sink chunk by chunk as the HTTP layer makes them.
//!
//! Run with `cargo bench --bench output`; ids are `output/<format>/100000`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
#[path = "support/franke.rs"]
mod support;

use meshfit::geom::Rect;
use meshfit::output::{self, Format, Options};
use meshfit::refine::{Params, refine};
use meshfit::result::RunResult;
use std::sync::Arc;
use support::franke;

fn formats(c: &mut Criterion) {
    let result: Arc<RunResult> =
        Arc::new(refine(&franke, Rect::unit(), &Params::new(100_000).unwrap(), &mut ()).unwrap().into());
    let options = Options { id: Some("0".repeat(64)), ..Options::default() };
    let mut group = c.benchmark_group("output");
    group.sample_size(10);
    group.throughput(Throughput::Elements(result.vertices.len() as u64));
    for &format in Format::ALL {
        group.bench_function(format!("{format}/100000"), |b| {
            b.iter(|| output::encode(&result, format, &options).into_chunks().map(|c| c.len()).sum::<usize>())
        });
    }
    group.finish();
}

criterion_group!(benches, formats);
criterion_main!(benches);
