//! A tile's mesh from a DEM, crack-free by construction.
//!
//! Every level has one lattice over the globe, `samples` − 1 steps a tile side, so a tile's
//! lattice nodes on a side are its neighbour's on the same side, at the same positions bit
//! for bit (the spacing is a power of two of a degree). The DEM is sampled there bilinearly;
//! outside its extent its nearest edge is extended, fading to [`FILL`] over one DEM size
//! ([`height`]): the DEM's own edge samples stay right, and far from it every tile, the
//! DEM's or not, agrees with its neighbours (the two roots, the antimeridian).
//!
//! Each side's profile is simplified on its own to the tolerance (Douglas–Peucker, from the
//! side's values alone), and the tile is refined from its corners and those side nodes by
//! greedy node insertion, never adding a node on a side ([`refine_with_sides`]). Two tiles
//! that share a side then share its vertices and heights, whichever was made first and on
//! whichever machine. Every sample of the DEM inside a tile off its sides is within the
//! tolerance of its mesh: the lattice resamples the DEM between its samples, so a triangle
//! over the DEM is measured at the DEM's own samples and the worst one inserted itself; a
//! triangle beyond the DEM, at the lattice's nodes. A sample on a side is left to the side's
//! nodes, chosen on the lattice's profile.

use super::ellipsoid::SEMI_MAJOR_AXIS;
use super::scheme::{TileId, degrees_per_tile};
use super::view::View;
use crate::geom::{Point, Rect};
use crate::refine::{Criterion, Method, Params, SAMPLE_CLEARANCE, Sides, refine_with_sides};
use crate::source::{Grid, node_coordinate};

/// The height far from the DEM: the ellipsoid's surface.
pub const FILL: f64 = 0.0;

/// The DEM's height at `p` (bilinear); outside its extent, its nearest edge's height fading
/// linearly to [`FILL`] over the DEM's larger side, measured the larger way off (in degrees).
/// A cliff at the edge would spoil the DEM's last samples in every tile that straddles it.
pub fn height(dem: &View<'_>, p: Point) -> f64 {
    let r = dem.rect();
    let off = (r.x0() - p.x).max(p.x - r.x1()).max(r.y0() - p.y).max(p.y - r.y1());
    if off <= 0.0 {
        return dem.eval(p);
    }
    let fade = (r.x1() - r.x0()).max(r.y1() - r.y0());
    let weight = (1.0 - off / fade).max(0.0);
    // Grid::eval clamps to the nearest edge.
    FILL + (dem.eval(p) - FILL) * weight
}

/// A tile's triangles over its vertices: longitude and latitude in degrees, height in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct TileSurface {
    /// (lon, lat, height) of each vertex.
    pub vertices: Vec<[f64; 3]>,
    /// Vertex triples, counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
}

/// The mesh of `tile` over `dem` (samples whose domain is in degrees: x longitude, y latitude)
/// within `tolerance` metres of the DEM at every sample of the DEM inside the tile but those
/// on or within two hundredths of a step of its sides (which are left to the sides' nodes),
/// and beyond the DEM at every node of the tile's lattice of `steps` + 1 samples a side
/// (`steps` a power of two).
///
/// # Panics
/// When `steps` is not a power of two of at least 2, or `tolerance` is not finite and ≥ 0.
pub fn mesh_tile(dem: &View<'_>, tile: TileId, tolerance: f64, steps: usize) -> TileSurface {
    assert!(steps >= 2 && steps.is_power_of_two(), "steps {steps} is not a power of two");
    let b = tile.bounds();
    let rect = Rect::new(b.west, b.east, b.south, b.north).expect("a tile is a proper rectangle");
    let n = steps + 1;
    // The lattice's positions: the nodes the grid made of its values will have.
    let lons: Vec<f64> = (0..n).map(|i| node_coordinate(i, n, rect.x0(), rect.x1())).collect();
    let lats: Vec<f64> = (0..n).map(|j| node_coordinate(j, n, rect.y0(), rect.y1())).collect();
    let values =
        lats.iter().flat_map(|&lat| lons.iter().map(move |&lon| height(dem, Point::new(lon, lat)))).collect();
    let lattice = Grid::new(n, n, values).expect("a DEM gives finite heights").with_domain(rect);
    let row = |j: usize| (0..n).map(|i| lattice.value(i, j)).collect::<Vec<_>>();
    let column = |i: usize| (0..n).map(|j| lattice.value(i, j)).collect::<Vec<_>>();
    // The Earth's curvature: clients draw straight triangles between Earth-centred points,
    // which sag below the surface by about R·θ²/4 over a cell θ radians a side. A uniform grid
    // of k × k cells, k from the level and tolerance alone (so neighbours agree), keeps the
    // sag within half the tolerance.
    let cells = curvature_cells(tile, tolerance, steps);
    let every = steps / cells;
    let uniform: Vec<usize> = (1..cells).map(|c| c * every).collect();
    let with_uniform = |mut kept: Vec<usize>| {
        kept.extend(&uniform);
        kept.sort_unstable();
        kept.dedup();
        kept
    };
    let sides = Sides {
        south: with_uniform(simplify(&row(0), tolerance)),
        east: with_uniform(simplify(&column(n - 1), tolerance)),
        north: with_uniform(simplify(&row(n - 1), tolerance)),
        west: with_uniform(simplify(&column(0), tolerance)),
        seeds: uniform.iter().flat_map(|&j| uniform.iter().map(move |&i| (i, j))).collect(),
    };
    let params = Params::builder(n * n)
        .criterion(Criterion::Error)
        .method(Method::SemiRecursive)
        .tolerance(tolerance)
        .on_grid(true)
        .build()
        .expect("a tolerance ≥ 0 and a budget of the lattice's nodes");
    // The error is measured at the DEM's own samples too: the lattice resamples them. Those
    // on or next to a side are left to it (its nodes hold it within the tolerance).
    let samples = dem.samples_inside(rect, clearance(rect, steps));
    let refinement = refine_with_sides(&lattice, &sides, samples.as_ref(), &params, &mut ());
    let mesh = &refinement.mesh;
    TileSurface {
        vertices: mesh.vertices().iter().map(|v| [v.x, v.y, v.z]).collect(),
        triangles: mesh.triangles().collect(),
    }
}

/// How far from a tile's sides, in degrees, the DEM's samples it is measured at lie: those
/// nearer are left to the sides' nodes.
pub(super) fn clearance(rect: Rect, steps: usize) -> f64 {
    2.0 * SAMPLE_CLEARANCE * (rect.x1() - rect.x0()) / steps as f64
}

/// Cells a side of `tile` is cut into so that the chord of a cell's diagonal sags at most
/// half of `tolerance` below the ellipsoid: a power of two, at most `steps`.
fn curvature_cells(tile: TileId, tolerance: f64, steps: usize) -> usize {
    let theta = degrees_per_tile(tile.z).to_radians();
    // R·(θ/k)²/4 ≤ tolerance/2.
    let needed = theta / (2.0 * tolerance / SEMI_MAJOR_AXIS).sqrt();
    if needed.is_nan() || needed >= steps as f64 {
        return steps;
    }
    (needed.ceil().max(1.0) as usize).next_power_of_two().min(steps)
}

/// The samples a profile keeps, besides its ends, for its linear interpolation to stay within
/// `tolerance` of every sample (Douglas–Peucker: split at the worst sample while it is off by
/// more), in increasing order. A function of the values alone.
pub fn simplify(values: &[f64], tolerance: f64) -> Vec<usize> {
    let mut kept = Vec::new();
    let mut pending = vec![(0, values.len() - 1)];
    while let Some((a, b)) = pending.pop() {
        let (va, vb) = (values[a], values[b]);
        let line = |s: usize| va + (vb - va) * ((s - a) as f64 / (b - a) as f64);
        // The first of equally bad samples.
        let worst = (a + 1..b).map(|s| (s, (values[s] - line(s)).abs())).fold(
            None,
            |best: Option<(usize, f64)>, (s, e)| {
                if best.is_none_or(|(_, worst)| e > worst) { Some((s, e)) } else { best }
            },
        );
        if let Some((s, error)) = worst
            && error > tolerance
        {
            kept.push(s);
            pending.extend([(a, s), (s, b)]);
        }
    }
    kept.sort_unstable();
    kept
}

#[cfg(test)]
mod tests;
