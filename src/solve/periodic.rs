//! Periodic and antiperiodic pairs of sides: before each solve the mesh gets a vertex on each
//! side of a pair wherever the other side has one, so that the solve can make the two one
//! unknown (`Numbering`). Refinement splits each side on its own; this puts the missing
//! partners in, each by a split of the boundary edge it falls on (then Lawson's flips).

use super::error::SolveError;
use super::problem::Problem;
use crate::geom::{Mesh, NONE, Vertex};
use crate::refine::Method;
use std::collections::HashSet;

/// Gives every vertex on a side of a periodic pair a partner on the other side; returns
/// whether the mesh changed.
///
/// # Errors
/// [`SolveError::Unmatched`] when a partner cannot go in (its split would make a triangle of
/// no area: the side is resolved to the last bit there).
pub(super) fn match_sides(
    mesh: &mut Mesh,
    problem: &Problem<'_>,
    method: Method,
) -> Result<bool, SolveError> {
    let (d, boundary) = (problem.domain(), problem.boundary());
    let mut stack = Vec::new();
    let mut changed = false;
    if boundary.across_x().is_some() {
        for (from, to) in [(d.x0(), d.x1()), (d.x1(), d.x0())] {
            for y in missing(mesh, |v| v.x == from, |v| v.x == to, |v| v.y) {
                insert(mesh, method, &mut stack, Vertex { x: to, y, z: 0.0 }, true)?;
                changed = true;
            }
        }
    }
    if boundary.across_y().is_some() {
        for (from, to) in [(d.y0(), d.y1()), (d.y1(), d.y0())] {
            for x in missing(mesh, |v| v.y == from, |v| v.y == to, |v| v.x) {
                insert(mesh, method, &mut stack, Vertex { x, y: to, z: 0.0 }, false)?;
                changed = true;
            }
        }
    }
    Ok(changed)
}

/// The positions (by `along`) of the vertices `from` holds that `to` lacks, in vertex order.
fn missing(
    mesh: &Mesh,
    from: impl Fn(&Vertex) -> bool,
    to: impl Fn(&Vertex) -> bool,
    along: impl Fn(&Vertex) -> f64,
) -> Vec<f64> {
    let have: HashSet<u64> =
        mesh.vertices().iter().filter(|v| to(v)).map(|v| (along(v) + 0.0).to_bits()).collect();
    (mesh.vertices().iter().filter(|v| from(v)))
        .map(|v| along(v) + 0.0)
        .filter(|t| !have.contains(&t.to_bits()))
        .collect()
}

/// Splits the boundary edge that `m` falls on (a vertical side when `vertical`), with z
/// interpolated along it, then flips as `method` does.
fn insert(
    mesh: &mut Mesh,
    method: Method,
    stack: &mut Vec<u32>,
    mut m: Vertex,
    vertical: bool,
) -> Result<(), SolveError> {
    let unmatched = SolveError::Unmatched { x: m.x, y: m.y };
    let (at, along) = if vertical { (m.x, m.y) } else { (m.y, m.x) };
    let key = |v: Vertex| if vertical { (v.x, v.y) } else { (v.y, v.x) };
    let e = (0..mesh.num_halfedges() as u32).find(|&e| {
        let (a, b) = (key(mesh.vertex(mesh.origin(e))), key(mesh.vertex(mesh.dest(e))));
        mesh.twin(e) == NONE && a.0 == at && b.0 == at && a.1.min(b.1) < along && along < a.1.max(b.1)
    });
    let Some(e) = e else { return Err(unmatched) };
    let (a, b) = (mesh.vertex(mesh.origin(e)), mesh.vertex(mesh.dest(e)));
    let t = (along - key(a).1) / (key(b).1 - key(a).1);
    m.z = a.z + t * (b.z - a.z);
    if !mesh.can_split(e, m.point(), 0.0) {
        return Err(unmatched);
    }
    let split = mesh.split(e, m);
    if method == Method::SemiRecursive {
        stack.extend(split.suspects());
        mesh.legalize_all(stack, |_, _| {});
    }
    Ok(())
}
