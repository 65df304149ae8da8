use super::*;
use crate::geom::Point;
use crate::source::{Grid, GridHints, decode_grid};
use crate::tiles::{Pyramid, TileId, Wanted, degrees_per_tile};
use std::io::Cursor;

const NODATA: f32 = -9999.0;

/// Heights over 10°–11.5°E, 45°–46°N, `nx` × `ny` samples (image rows from the north), with
/// nodata where `hole(i, row)`.
fn heights(nx: usize, ny: usize, hole: impl Fn(usize, usize) -> bool) -> Vec<f32> {
    (0..ny)
        .flat_map(|row| (0..nx).map(move |i| (i, row)))
        .map(|(i, row)| {
            if hole(i, row) {
                return NODATA;
            }
            let (x, y) = (i as f32 / nx as f32, row as f32 / ny as f32);
            700.0 + 300.0 * (x * 9.0).sin() * (y * 7.0).cos() + 60.0 * (x * 41.0 + y * 29.0).sin()
        })
        .collect()
}

/// The GeoKeyDirectory of EPSG:4326, and the pixel scale and tie point of `nx` × `ny`
/// samples over 10°–11.5°E, 45°–46°N (PixelIsArea: the tie point is the corner).
fn georeference(nx: usize, ny: usize) -> ([u16; 12], [f64; 3], [f64; 6]) {
    let (sx, sy) = (1.5 / nx as f64, 1.0 / ny as f64);
    ([1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326], [sx, sy, 0.0], [0.0, 0.0, 0.0, 10.0, 46.0, 0.0])
}

/// A GeoTIFF of `values` in strips, as the tiff crate writes it.
fn striped(nx: usize, ny: usize, values: &[f32], nodata: bool) -> Vec<u8> {
    use ::tiff::encoder::{TiffEncoder, colortype};
    use ::tiff::tags::Tag;
    let (keys, scale, tiepoint) = georeference(nx, ny);
    let mut bytes = Vec::new();
    let mut encoder = TiffEncoder::new(Cursor::new(&mut bytes)).unwrap();
    let mut image = encoder.new_image::<colortype::Gray32Float>(nx as u32, ny as u32).unwrap();
    image.encoder().write_tag(Tag::ModelPixelScaleTag, &scale[..]).unwrap();
    image.encoder().write_tag(Tag::ModelTiepointTag, &tiepoint[..]).unwrap();
    image.encoder().write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap();
    if nodata {
        image.encoder().write_tag(Tag::GdalNodata, "-9999").unwrap();
    }
    image.write_data(values).unwrap();
    bytes
}

/// A GeoTIFF of `values` in uncompressed tiles of `bw` × `bh` (multiples of 16), written by
/// hand: the tiff crate's encoder writes strips only.
fn tiled(nx: usize, ny: usize, values: &[f32], [bw, bh]: [usize; 2], nodata: bool) -> Vec<u8> {
    let (keys, scale, tiepoint) = georeference(nx, ny);
    let (across, down) = (nx.div_ceil(bw), ny.div_ceil(bh));
    // The tiles first, after the 8-byte header; edge tiles padded to the full size.
    let mut data = Vec::new();
    for by in 0..down {
        for bx in 0..across {
            for r in 0..bh {
                for c in 0..bw {
                    let (i, row) = (bx * bw + c, by * bh + r);
                    let v = if i < nx && row < ny { values[row * nx + i] } else { 0.0 };
                    data.extend(v.to_le_bytes());
                }
            }
        }
    }
    let tile_bytes = (bw * bh * 4) as u32;
    let offsets: Vec<u32> = (0..across * down).map(|k| 8 + k as u32 * tile_bytes).collect();
    // Then the values too long for an entry, then the directory.
    let mut extra = Vec::new();
    let place = |bytes: Vec<u8>, extra: &mut Vec<u8>| {
        let at = 8 + data.len() as u32 + extra.len() as u32;
        extra.extend(bytes);
        at
    };
    let le32 = |v: &[u32]| v.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    let le64 = |v: &[f64]| v.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    let at_offsets = place(le32(&offsets), &mut extra);
    let at_counts = place(le32(&vec![tile_bytes; offsets.len()]), &mut extra);
    let at_scale = place(le64(&scale), &mut extra);
    let at_tie = place(le64(&tiepoint), &mut extra);
    let at_keys = place(keys.iter().flat_map(|k| k.to_le_bytes()).collect(), &mut extra);
    let at_nodata = place(b"-9999\0".to_vec(), &mut extra);
    // (tag, type, count, value or offset): SHORT 3, LONG 4, DOUBLE 12, ASCII 2.
    let mut entries: Vec<(u16, u16, u32, u32)> = vec![
        (256, 4, 1, nx as u32),
        (257, 4, 1, ny as u32),
        (258, 3, 1, 32),
        (259, 3, 1, 1),
        (262, 3, 1, 1),
        (277, 3, 1, 1),
        (322, 4, 1, bw as u32),
        (323, 4, 1, bh as u32),
        (324, 4, offsets.len() as u32, at_offsets),
        (325, 4, offsets.len() as u32, at_counts),
        (339, 3, 1, 3),
        (33550, 12, 3, at_scale),
        (33922, 12, 6, at_tie),
        (34735, 3, 12, at_keys),
    ];
    if nodata {
        entries.push((42113, 2, 6, at_nodata));
    }
    let ifd = 8 + (data.len() + extra.len()) as u32;
    let mut bytes = b"II*\0".to_vec();
    bytes.extend(ifd.to_le_bytes());
    bytes.extend(data);
    bytes.extend(extra);
    bytes.extend((entries.len() as u16).to_le_bytes());
    for (tag, kind, count, value) in entries {
        bytes.extend(tag.to_le_bytes());
        bytes.extend(kind.to_le_bytes());
        bytes.extend(count.to_le_bytes());
        bytes.extend(value.to_le_bytes());
    }
    bytes.extend(0u32.to_le_bytes());
    bytes
}

fn open(bytes: Vec<u8>) -> Dem {
    Dem::open(Box::new(Cursor::new(bytes)), usize::MAX).unwrap()
}

/// The whole grid of a file, its domain applied, as a caller holding it in memory has it.
fn whole(bytes: &[u8]) -> Grid {
    let decoded = decode_grid(bytes, &GridHints::default(), usize::MAX).unwrap();
    decoded.grid.with_domain(decoded.domain.unwrap())
}

#[test]
fn a_tiled_file_gives_every_tile_a_striped_one_does_bit_for_bit() {
    // 300 × 200 in tiles of 64 × 48: the last column and row of blocks are partial.
    let (nx, ny) = (300, 200);
    let values = heights(nx, ny, |_, _| false);
    let (striped, tiled) =
        (open(striped(nx, ny, &values, false)), open(tiled(nx, ny, &values, [64, 48], false)));
    assert_eq!(tiled.file.block_size(), [64, 48]);
    assert_ne!(striped.file.block_size(), [64, 48]);
    assert_eq!(striped.heights(), tiled.heights());
    let (a, b) = (Pyramid::new(&striped, 0, None, 1.0).unwrap(), Pyramid::new(&tiled, 0, None, 1.0).unwrap());
    let tiles = a.tiles();
    assert_eq!(tiles, b.tiles());
    assert!(tiles.len() > 20, "{} tiles", tiles.len());
    for &tile in &tiles {
        assert_eq!(a.tile(tile, Wanted::ALL).unwrap(), b.tile(tile, Wanted::ALL).unwrap(), "{tile:?}");
    }
}

#[test]
fn a_view_interpolates_as_the_whole_grid_does_bit_for_bit_from_a_window_or_sparse_samples() {
    let (nx, ny) = (300, 200);
    let values = heights(nx, ny, |_, _| false);
    let file = tiled(nx, ny, &values, [32, 32], false);
    let (dem, grid) = (open(file.clone()), whole(&file));
    // A root (beyond the DEM too), a tile over all of it and tiles over part, across its
    // edge and beside it.
    for (z, x, y) in [(0, 0, 0), (6, 35, 23), (8, 142, 92), (9, 285, 184), (9, 283, 186)] {
        let tile = TileId::new(z, x, y).unwrap();
        let b = tile.bounds();
        let rect = Rect::new(b.west, b.east, b.south, b.north).unwrap();
        let steps = 64;
        let step = degrees_per_tile(tile.z) / steps as f64;
        for limit in [0, usize::MAX] {
            let view = dem.view_within(rect, steps, step, limit).unwrap();
            let n = steps + 1;
            let xs = (0..n).map(|k| node_coordinate(k, n, rect.x0(), rect.x1()));
            let ys: Vec<f64> = (0..n).map(|k| node_coordinate(k, n, rect.y0(), rect.y1())).collect();
            for x in xs {
                for &y in &ys {
                    for (dx, dy) in [(0.0, 0.0), (step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step)] {
                        let p = Point::new(x + dx, y + dy);
                        assert_eq!(
                            view.eval(p).to_bits(),
                            grid.interpolate(p).to_bits(),
                            "{tile:?} at {p:?}"
                        );
                    }
                }
            }
            let whole_view = View::whole(&grid);
            let clear = clearance(rect, steps);
            let (mine, theirs) = (view.samples_inside(rect, clear), whole_view.samples_inside(rect, clear));
            if limit == 0 {
                assert!(mine.is_none(), "sparse samples are not measured at");
            } else {
                assert_eq!(mine, theirs, "{tile:?}");
            }
        }
    }
}

#[test]
fn whether_a_tile_holds_data_is_exact_at_the_samples_of_blocks_with_holes() {
    // A disc of data in a sea of nodata, in blocks of 16: some blocks all data, some none,
    // the rest both.
    let (nx, ny) = (160, 96);
    let hole = |i: usize, row: usize| {
        let (dx, dy) = (i as f64 - 80.0, row as f64 - 48.0);
        dx * dx + dy * dy > 40.0 * 40.0
    };
    let dem = open(tiled(nx, ny, &heights(nx, ny, hole), [16, 16], true));
    let holes = (0..nx * ny).filter(|&k| hole(k % nx, k / nx)).count();
    assert_eq!(dem.filled(), holes as u64);
    assert!(dem.data.contains(&0) && dem.data.contains(&256) && !dem.holes.is_empty());
    let grid_x = |i: usize| 10.0 + 1.5 * (i as f64 + 0.5) / nx as f64;
    let grid_y = |row: usize| 46.0 - (row as f64 + 0.5) / ny as f64;
    // Every window of 1 to 4 samples a side: data in it or not, brute force.
    let mut seen = [0, 0];
    for row0 in (0..ny - 4).step_by(3) {
        for i0 in (0..nx - 4).step_by(3) {
            for size in 1..=4 {
                let (i1, row1) = (i0 + size - 1, row0 + size - 1);
                // Bounds through the corner samples, or a third of a pixel short of them.
                for shrink in [0.0, 0.3] {
                    let (px, py) = (1.5 / nx as f64, 1.0 / ny as f64);
                    let bounds = Bounds {
                        west: grid_x(i0) - shrink * px,
                        east: grid_x(i1) + shrink * px,
                        south: grid_y(row1) - shrink * py,
                        north: grid_y(row0) + shrink * py,
                    };
                    let want = (row0..=row1).any(|r| (i0..=i1).any(|i| !hole(i, r)));
                    assert_eq!(dem.has_data(&bounds), want, "columns {i0}..={i1}, rows {row0}..={row1}");
                    seen[usize::from(want)] += 1;
                }
            }
        }
    }
    assert!(seen[0] > 100 && seen[1] > 100, "{seen:?}");
}

#[test]
fn holes_are_filled_within_their_block_and_empty_blocks_from_the_blocks_nearest() {
    // Blocks of 16: column of blocks 0 wholly nodata, block (1, 0) with a hole of 4 × 4.
    let (nx, ny) = (48, 32);
    let hole = |i: usize, row: usize| i < 16 || ((20..24).contains(&i) && (4..8).contains(&row));
    let values = heights(nx, ny, hole);
    let dem = open(tiled(nx, ny, &values, [16, 16], true));
    // The empty blocks take the mean of the means of the blocks of data next to them:
    // (1, 0) and (1, 1) for both.
    let mean_of = |block: &Block| {
        let data: Vec<f64> = (0..block.values.len())
            .filter(|&k| !block.holes.as_ref().is_some_and(|h| h[k]))
            .map(|k| block.values[k])
            .collect();
        data.iter().sum::<f64>() / data.len() as f64
    };
    let beside = [dem.block(1, [1, 0]).unwrap(), dem.block(4, [1, 1]).unwrap()];
    let mean = (mean_of(&beside[0]) + mean_of(&beside[1])) / 2.0;
    for by in 0..2 {
        let empty = dem.block(by * 3, [0, by]).unwrap();
        assert!(empty.values.iter().all(|&v| v == mean), "block row {by}: {} vs {mean}", empty.values[0]);
    }
    // The hole in block (1, 0) from its own data: between the heights around it.
    let block = dem.block(1, [1, 0]).unwrap();
    let filled = block.values[5 * 16 + 5];
    assert!((600.0..1100.0).contains(&filled), "{filled}");
    assert!(block.holes.as_ref().unwrap()[5 * 16 + 5]);
    // A fresh reader, reading the blocks the other way round, fills them the same.
    let again = open(tiled(nx, ny, &values, [16, 16], true));
    for index in (0..6).rev() {
        let at = [index % 3, index / 3];
        assert_eq!(again.block(index, at).unwrap(), dem.block(index, at).unwrap());
    }
}

#[test]
fn a_truncated_tiled_file_and_one_all_nodata_are_refused_naming_why() {
    let (nx, ny) = (64, 32);
    let mut file = tiled(nx, ny, &heights(nx, ny, |_, _| false), [32, 32], false);
    // Cut inside the tiles: the directory at the end is gone.
    file.truncate(3000);
    let error = Dem::open(Box::new(Cursor::new(file)), usize::MAX).unwrap_err();
    assert!(matches!(error, DemError::File(GridFileError::Corrupt { .. })), "{error}");
    let empty = tiled(nx, ny, &heights(nx, ny, |_, _| true), [32, 32], true);
    let error = Dem::open(Box::new(Cursor::new(empty)), usize::MAX).unwrap_err();
    assert_eq!(error, DemError::File(GridFileError::AllNoData(-9999.0)));
}
