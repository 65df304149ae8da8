use super::*;
use crate::geom::Point;
use crate::tiles::View;
use proptest::prelude::*;

/// A DEM of hills and a ridge over 10°–12°E, 45°–46°N, 401 × 201 samples (18 arc-seconds).
fn dem(seed: f64) -> Grid {
    let (nx, ny) = (401, 201);
    let values = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| (i, j)))
        .map(|(i, j)| {
            let (x, y) = (f64::from(i) / 200.0, f64::from(j) / 200.0);
            800.0
                + 400.0 * (x * 7.0 + seed).sin() * (y * 5.0).cos()
                + 150.0 * (-(x - y - 0.3).powi(2) * 80.0).exp()
        })
        .collect();
    Grid::new(nx as usize, ny as usize, values)
        .unwrap()
        .with_domain(Rect::new(10.0, 12.0, 45.0, 46.0).unwrap())
}

/// The corners of a triangle of `surface` holding `p` (in lon, lat) and `p`'s barycentric
/// weights in it.
fn locate(surface: &TileSurface, p: Point) -> ([[f64; 3]; 3], [f64; 3]) {
    for t in &surface.triangles {
        let [a, b, c] = t.map(|k| surface.vertices[k as usize]);
        let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
        let l1 = ((p.x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p.y - a[1])) / det;
        let l2 = ((b[0] - a[0]) * (p.y - a[1]) - (p.x - a[0]) * (b[1] - a[1])) / det;
        let l0 = 1.0 - l1 - l2;
        if [l0, l1, l2].iter().all(|&l| l >= -1e-9) {
            return ([a, b, c], [l0, l1, l2]);
        }
    }
    panic!("({}, {}) is in no triangle", p.x, p.y);
}

/// The tile's mesh evaluated at `p` (inside the tile): the plane of a triangle holding it.
fn linear(surface: &TileSurface, p: Point) -> f64 {
    let (corners, weights) = locate(surface, p);
    (0..3).map(|k| weights[k] * corners[k][2]).sum()
}

/// The vertices of `surface` on the line lon = `lon` (or lat = `lat`), sorted.
fn on_line(surface: &TileSurface, test: impl Fn(&[f64; 3]) -> bool) -> Vec<[u64; 3]> {
    let mut line: Vec<[u64; 3]> =
        surface.vertices.iter().filter(|v| test(v)).map(|v| v.map(f64::to_bits)).collect();
    line.sort_unstable();
    line
}

#[test]
fn neighbours_share_every_vertex_of_their_common_side_bit_for_bit() {
    let dem = dem(0.0);
    // Level 9 tiles are 0.3515625° a side; these meet at 10.546875°E and 45.3515625°N.
    let (z, x, y) = (9, 541, 384);
    let tile = |x, y| TileId::new(z, x, y).unwrap();
    let tolerance = 2.0;
    let here = mesh_tile(&View::whole(&dem), tile(x, y), tolerance, 64);
    let east = mesh_tile(&View::whole(&dem), tile(x + 1, y), tolerance, 64);
    let north = mesh_tile(&View::whole(&dem), tile(x, y + 1), tolerance, 64);
    let b = tile(x, y).bounds();
    let shared_east = on_line(&here, |v| v[0] == b.east);
    assert_eq!(shared_east, on_line(&east, |v| v[0] == b.east));
    let shared_north = on_line(&here, |v| v[1] == b.north);
    assert_eq!(shared_north, on_line(&north, |v| v[1] == b.north));
    // The sides are simplified, not kept whole, and not left bare.
    assert!(shared_east.len() > 2 && shared_east.len() < 65, "{}", shared_east.len());
    assert!(here.vertices.len() < 65 * 65 / 4, "{} vertices", here.vertices.len());
}

#[test]
fn beyond_the_dem_every_lattice_node_is_within_the_tolerance() {
    // East of the DEM (which ends at 12°E), where its edge fades: no sample of it, so the
    // lattice's nodes are what the tile follows.
    let dem = dem(1.3);
    let tile = TileId::new(10, 1095, 770).unwrap();
    assert!(tile.bounds().west > 12.0);
    for tolerance in [0.5, 5.0, 40.0] {
        let surface = mesh_tile(&View::whole(&dem), tile, tolerance, 32);
        let worst = worst_at_lattice(&dem, tile, &surface, 32, |_| true);
        assert!(worst <= tolerance * (1.0 + 1e-9) + 1e-9, "{worst} > {tolerance}");
    }
}

/// The largest |mesh − height| over the nodes of `tile`'s lattice of `steps` a side for
/// which `keep` holds, the height faded beyond the DEM as the tiles make it.
fn worst_at_lattice(
    dem: &Grid,
    tile: TileId,
    surface: &TileSurface,
    steps: u32,
    keep: impl Fn(Point) -> bool,
) -> f64 {
    let b = tile.bounds();
    let at = |k: u32, lo: f64, hi: f64| lo + (hi - lo) * f64::from(k) / f64::from(steps);
    (0..=steps)
        .flat_map(|j| (0..=steps).map(move |i| (i, j)))
        .map(|(i, j)| Point::new(at(i, b.west, b.east), at(j, b.south, b.north)))
        .filter(|&p| keep(p))
        .map(|p| (linear(surface, p) - height(&View::whole(dem), p)).abs())
        .fold(0.0, f64::max)
}

/// The largest |mesh − DEM| over the DEM's own samples inside `tile`: those off its sides,
/// and those on them.
fn worst_at_samples(dem: &Grid, tile: TileId, surface: &TileSurface) -> (f64, f64) {
    let b = tile.bounds();
    let (mut inside, mut on_sides) = (0.0f64, 0.0f64);
    for j in 0..dem.ny() {
        for i in 0..dem.nx() {
            let p = dem.node(i, j);
            if (b.west..=b.east).contains(&p.x) && (b.south..=b.north).contains(&p.y) {
                let error = (linear(surface, p) - dem.value(i, j)).abs();
                if p.x == b.west || p.x == b.east || p.y == b.south || p.y == b.north {
                    on_sides = on_sides.max(error);
                } else {
                    inside = inside.max(error);
                }
            }
        }
    }
    (inside, on_sides)
}

#[test]
fn every_dem_sample_in_a_tile_is_within_the_tolerance() {
    // The lattice (64 steps over 35 pixels) resamples the DEM: its nodes are not the DEM's.
    let dem = dem(1.3);
    let tile = TileId::new(10, 1086, 770).unwrap();
    for tolerance in [0.5, 5.0, 40.0] {
        let surface = mesh_tile(&View::whole(&dem), tile, tolerance, 64);
        let (inside, on_sides) = worst_at_samples(&dem, tile, &surface);
        assert_eq!(on_sides, 0.0, "no sample of this DEM lies on the tile's sides");
        assert!(inside <= tolerance * (1.0 + 1e-9) + 1e-9, "{inside} > {tolerance}");
    }
}

#[test]
fn samples_on_a_tiles_sides_are_left_to_them_and_every_one_inside_is_within_the_tolerance() {
    // 1/256° pixels from 10°E, 45°N: a level-10 tile's sides (45/256° apart) run along the
    // DEM's rows and columns, so samples lie on every side, where no vertex may be added.
    let (nx, ny) = (513, 257);
    let values = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| (f64::from(i) / 256.0, f64::from(j) / 256.0)))
        .map(|(x, y)| 600.0 + 300.0 * (x * 9.0).sin() * (y * 11.0).cos() + 80.0 * (x * 40.0 + y * 30.0).sin())
        .collect();
    let dem = Grid::new(nx as usize, ny as usize, values)
        .unwrap()
        .with_domain(Rect::new(10.0, 12.0, 45.0, 46.0).unwrap());
    let tile = TileId::new(10, 1081, 768).unwrap();
    let b = tile.bounds();
    assert_eq!((b.west * 256.0).fract(), 0.0, "the tile's west side is a column of the DEM");
    for tolerance in [0.5, 5.0] {
        let surface = mesh_tile(&View::whole(&dem), tile, tolerance, 64);
        // Samples on a side are left to its nodes, simplified on the lattice's profile: they
        // may pass the tolerance (by a third here; see docs/tiles.md). Not one inside does.
        let (inside, on_sides) = worst_at_samples(&dem, tile, &surface);
        assert!(on_sides > 0.0, "samples lie on the sides");
        assert!(inside <= tolerance * (1.0 + 1e-9) + 1e-9, "{inside} > {tolerance}");
    }
}

#[test]
fn a_tile_across_the_dems_edge_keeps_its_samples_and_the_fade_beyond_within_the_tolerance() {
    // Level 10 tile 1092 spans 11.95°–12.13°E; a DEM of 0.04° ends at 12°E, its edge
    // fading to 0 over 0.04° beyond: steep, where only the lattice's nodes measure it.
    let values = (0..41 * 41).map(|k| 800.0 + 50.0 * (f64::from(k % 41) * 0.3).sin()).collect();
    let dem = Grid::new(41, 41, values).unwrap().with_domain(Rect::new(11.96, 12.0, 45.40, 45.44).unwrap());
    let tile = TileId::new(10, 1092, 770).unwrap();
    let b = tile.bounds();
    assert!(b.west < 12.0 && 12.0 < b.east);
    let tolerance = 2.0;
    let surface = mesh_tile(&View::whole(&dem), tile, tolerance, 64);
    let (inside, _) = worst_at_samples(&dem, tile, &surface);
    assert!(inside <= tolerance * (1.0 + 1e-9) + 1e-9, "{inside} > {tolerance} at the samples");
    let beyond = worst_at_lattice(&dem, tile, &surface, 64, |p| p.x > 12.0);
    assert!(beyond <= tolerance * (1.0 + 1e-9) + 1e-9, "{beyond} > {tolerance} beyond the DEM");
}

#[test]
fn a_tolerance_of_zero_keeps_every_node_and_a_large_one_the_corners() {
    let dem = dem(0.4);
    let tile = TileId::new(11, 2176, 1542).unwrap();
    assert_eq!(mesh_tile(&View::whole(&dem), tile, 0.0, 8).vertices.len(), 81);
    // A tolerance the data and the curvature of a level-11 tile meet with its corners alone.
    assert_eq!(mesh_tile(&View::whole(&dem), tile, 1e6, 8).vertices.len(), 4);
}

#[test]
fn beyond_the_dem_its_edge_fades_to_the_fill_and_sides_across_it_agree() {
    let dem = dem(0.0);
    let edge = dem.interpolate(Point::new(10.0, 45.5));
    // Just west of the DEM (10°E): its edge, barely faded; two degrees off (one DEM width):
    // the fill.
    assert!((height(&View::whole(&dem), Point::new(9.99, 45.5)) - edge).abs() < 0.01 * edge.abs());
    assert_eq!(height(&View::whole(&dem), Point::new(8.0, 45.5)), FILL);
    assert_eq!(height(&View::whole(&dem), Point::new(-150.0, -60.0)), FILL);
    // The tile astride the DEM's west edge and its western neighbour share their side.
    let (astride, off) = (TileId::new(9, 540, 385).unwrap(), TileId::new(9, 539, 385).unwrap());
    assert!(astride.bounds().west < 10.0 && astride.bounds().east > 10.0);
    let (a, b) =
        (mesh_tile(&View::whole(&dem), astride, 1.0, 64), mesh_tile(&View::whole(&dem), off, 1.0, 64));
    let side = astride.bounds().west;
    assert_eq!(on_line(&a, |v| v[0] == side), on_line(&b, |v| v[0] == side));
}

#[test]
fn large_tiles_follow_the_earths_curvature_within_the_tolerance() {
    use crate::tiles::{level_error, to_ecef};
    let dem = dem(0.0);
    for (z, x, y) in [(0, 0, 0), (1, 3, 0), (4, 20, 11)] {
        let tile = TileId::new(z, x, y).unwrap();
        let tolerance = level_error(tile.z);
        let surface = mesh_tile(&View::whole(&dem), tile, tolerance, 64);
        assert!(surface.vertices.len() > 4, "level {z} is more than two triangles");
        // Away from the DEM every height is the fill: what a client draws is the chord of each
        // triangle between Earth-centred points. Its gap to the ellipsoid at the lattice nodes:
        let b = tile.bounds();
        let mut worst = 0.0f64;
        for j in 0..=16 {
            for i in 0..=16 {
                let (lon, lat) = (
                    b.west + (b.east - b.west) * f64::from(i) / 16.0,
                    b.south + (b.north - b.south) * f64::from(j) / 16.0,
                );
                if dem.rect().contains(Point::new(lon, lat)) {
                    continue;
                }
                let (corners, l) = locate(&surface, Point::new(lon, lat));
                let [pa, pb, pc] = corners.map(|v| to_ecef(v[0], v[1], v[2]));
                let q: [f64; 3] = std::array::from_fn(|k| l[0] * pa[k] + l[1] * pb[k] + l[2] * pc[k]);
                let p = to_ecef(lon, lat, 0.0);
                worst = worst.max(((0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>()).sqrt());
            }
        }
        assert!(worst <= tolerance, "level {z}: the triangles sag {worst} m, past {tolerance}");
    }
}

#[test]
fn simplify_keeps_what_the_tolerance_needs() {
    let tent = [0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0];
    assert_eq!(simplify(&tent, 0.5), vec![3]);
    assert_eq!(simplify(&[5.0, 5.0, 5.0, 5.0], 0.0), Vec::<usize>::new());
    assert_eq!(simplify(&[0.0, 1.0, 0.0, 1.0, 0.0], 0.0), vec![1, 2, 3]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Any DEM, any pair of side-by-side tiles: the common side's vertices agree.
    #[test]
    fn random_dems_give_crack_free_neighbours(seed in 0.0f64..10.0, dx in 0u32..4, dy in 0u32..2, tolerance in 0.1f64..50.0, vertical in any::<bool>()) {
        let dem = dem(seed);
        let (x, y) = (541 + dx, 384 + dy);
        let a = TileId::new(9, x, y).unwrap();
        let b = if vertical { TileId::new(9, x, y + 1).unwrap() } else { TileId::new(9, x + 1, y).unwrap() };
        let (ma, mb) = (mesh_tile(&View::whole(&dem), a, tolerance, 32), mesh_tile(&View::whole(&dem), b, tolerance, 32));
        let bounds = a.bounds();
        if vertical {
            prop_assert_eq!(on_line(&ma, |v| v[1] == bounds.north), on_line(&mb, |v| v[1] == bounds.north));
        } else {
            prop_assert_eq!(on_line(&ma, |v| v[0] == bounds.east), on_line(&mb, |v| v[0] == bounds.east));
        }
    }
}
