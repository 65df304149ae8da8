//! A grid's mesh whose sides are fixed before it is refined: the nodes each side keeps are
//! chosen from that side's values alone, inserted first, and never added to. Two meshes of
//! neighbouring grids that share a side's nodes then share its vertices, whichever was made
//! first: terrain tiles without cracks.

use super::driver::finished;
use super::floors::Floors;
use super::nodes;
use super::observer::Observer;
use super::outcome::Refinement;
use super::params::{Criterion, Method, Params};
use super::run::Run;
use crate::geom::predicates::{Orientation, orientation};
use crate::geom::{Mesh, Point, Vertex};
use crate::source::Grid;
use std::time::Instant;

/// The nodes each side of a grid keeps besides its corners, by their index along the side
/// (column i on the south and north sides, row j on the west and east), strictly inside it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Sides {
    /// Row 0.
    pub south: Vec<usize>,
    /// Column nx − 1.
    pub east: Vec<usize>,
    /// Row ny − 1.
    pub north: Vec<usize>,
    /// Column 0.
    pub west: Vec<usize>,
    /// Nodes (i, j) inside the grid inserted after the sides, before any refinement: a
    /// floor on the mesh's resolution that the data alone would not ask for (a tile that must
    /// follow the Earth's curvature).
    pub seeds: Vec<(usize, usize)>,
}

/// Refines `grid` by greedy node insertion (criterion `error`), starting from its corners and
/// the nodes of `sides`, and never inserting another node on a side. With `samples`, the data
/// `grid` was resampled from (a DEM under a tile's lattice, in the same coordinates, clear of
/// its sides), a triangle that holds samples is measured at them rather than at the grid's
/// nodes, and its worst sample is inserted itself.
///
/// The sides' nodes should keep each side within the run's tolerance of its values (see
/// `tiles`, which simplifies each side's profile to it): a triangle whose worst node lies
/// on a side is then within the tolerance up to rounding, and is retired rather than split.
///
/// # Panics
/// When `params` are not criterion `error` with method `semi-recursive` or
/// `data-dependent` (the ones that insert nodes) and no `min_angle` (whose repairs split
/// sides), or a side's indices are not strictly increasing and strictly inside its side.
pub fn refine_with_sides<O: Observer>(
    grid: &Grid,
    sides: &Sides,
    samples: Option<&Grid>,
    params: &Params,
    observer: &mut O,
) -> Refinement {
    assert!(
        params.criterion() == Criterion::Error
            && params.method() != Method::Recursive
            && params.min_angle().is_none(),
        "fixed sides need criterion error by node insertion, with no angle repairs (they split sides)"
    );
    let start = Instant::now();
    let (nx, ny) = (grid.nx(), grid.ny());
    let (last_i, last_j) = (nx - 1, ny - 1);
    let corners = [(0, 0), (last_i, 0), (last_i, last_j), (0, last_j)];
    let mut mesh =
        Mesh::with_capacity(grid.rect(), corners.map(|(i, j)| grid.value(i, j)), params.max_vertices());
    let mut run = Run::new(params, observer, Floors::of_rect(grid.rect()));
    let mut evaluations = 4;
    // S₄'s sides run counter-clockwise, corner k to corner k + 1: south west to east, east
    // south to north, north east to west, west north to south. Each side's nodes go in that
    // order, each on the side's last piece.
    let inside = |k: &usize, n: usize| (1..n - 1).contains(k);
    for (side, name) in
        [(&sides.south, "south"), (&sides.east, "east"), (&sides.north, "north"), (&sides.west, "west")]
    {
        assert!(side.windows(2).all(|w| w[0] < w[1]), "the {name} side's nodes are not strictly increasing");
    }
    let along = [
        sides
            .south
            .iter()
            .inspect(|k| assert!(inside(k, nx), "south node {k}"))
            .map(|&i| (i, 0))
            .collect::<Vec<_>>(),
        sides
            .east
            .iter()
            .inspect(|k| assert!(inside(k, ny), "east node {k}"))
            .map(|&j| (last_i, j))
            .collect(),
        sides
            .north
            .iter()
            .inspect(|k| assert!(inside(k, nx), "north node {k}"))
            .rev()
            .map(|&i| (i, last_j))
            .collect(),
        sides
            .west
            .iter()
            .inspect(|k| assert!(inside(k, ny), "west node {k}"))
            .rev()
            .map(|&j| (0, j))
            .collect(),
    ];
    for (k, nodes) in along.iter().enumerate() {
        let end = (k as u32 + 1) % 4;
        let mut from = k as u32;
        for &(i, j) in nodes {
            let e = mesh.find_edge(from, end).expect("the side's last piece is an edge");
            let p = grid.node(i, j);
            let vertex = Vertex { x: p.x, y: p.y, z: grid.value(i, j) };
            // A lattice node is never within the area floor of a side's piece: a side node
            // skipped would break the guarantee the sides are fixed for.
            let split = run.insert_vertex(&mut mesh, e, vertex, |_, _| {}).expect("a side node is inserted");
            evaluations += 1;
            from = split.vertex;
        }
    }
    for &(i, j) in &sides.seeds {
        assert!(inside(&i, nx) && inside(&j, ny), "seed ({i}, {j}) is not inside the grid");
        let p = grid.node(i, j);
        let t = containing(&mesh, p).expect("the triangles tile the rectangle");
        let vertex = Vertex { x: p.x, y: p.y, z: grid.value(i, j) };
        let e = nodes::nearest_edge(&mesh, t, p);
        if run.insert_vertex(&mut mesh, e, vertex, |_, _| {}).is_some() {
            evaluations += 1;
        }
    }
    let (stop, errors) = nodes::refine(&mut mesh, grid, &mut run, &mut evaluations, true, samples);
    let round = run.finish(&mesh, stop, Some(errors));
    // Tiles are never paused (they run on their own bound, not a job's worker).
    finished(mesh, round, params, evaluations, start, std::time::Duration::ZERO)
}

/// A triangle of `mesh` that holds `p`, on its sides included (exact orientation tests); a
/// scan, for the few seeds a run starts with.
fn containing(mesh: &Mesh, p: Point) -> Option<u32> {
    (0..mesh.num_triangles() as u32).find(|&t| {
        let [a, b, c] = mesh.triangle(t as usize).map(|v| mesh.point(v));
        [(a, b), (b, c), (c, a)].iter().all(|&(u, w)| orientation(u, w, p) != Orientation::Clockwise)
    })
}
