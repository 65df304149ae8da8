//! Terrain tiles from the quick start's DEM (256 × 256 at one arc-second, in EPSG:4326): one
//! tile made, meshed, with normals and metadata, and encoded as quantized-mesh, at the levels
//! a map asks for first (a root), midway and deepest; and the whole pyramid on one thread.
//! What a cold tile costs the service (`GET /v1/tiles/{id}/{z}/{x}/{y}.terrain`, before gzip).
//!
//! Run with `cargo bench --bench tiles`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use meshfit::tiles::{Dem, Pyramid, TileId, Wanted};
use std::hint::black_box;

fn tiles(c: &mut Criterion) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/grids/dem-4326.tif");
    let file = std::fs::read(path).expect("the example DEM");
    let dem = Dem::open(Box::new(std::io::Cursor::new(file)), usize::MAX).unwrap();
    let pyramid = Pyramid::new(&dem, 0, None, 1.0).unwrap();
    let mut group = c.benchmark_group("tiles");
    group.sample_size(20);
    // The first tile of each level the DEM covers, at the levels named.
    for z in [0, 10, 14] {
        let ([x, _], [y, _]) = pyramid.available(z).unwrap();
        let tile = TileId { z, x: if z == 0 { 0 } else { x }, y };
        group.bench_function(format!("tile/z{z}"), |b| {
            b.iter(|| pyramid.tile(black_box(tile), Wanted::ALL).unwrap())
        });
    }
    let all = pyramid.tiles();
    group.throughput(Throughput::Elements(all.len() as u64));
    group.bench_function(format!("pyramid/{}_tiles", all.len()), |b| {
        b.iter(|| {
            all.iter()
                .map(|&t| pyramid.tile(t, Wanted::ALL).unwrap().map_or(0, |bytes| bytes.len()))
                .sum::<usize>()
        })
    });
    group.finish();
}

criterion_group!(benches, tiles);
criterion_main!(benches);
