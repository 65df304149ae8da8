//! Repairs that keep criterion `error`'s triangles from turning into needles.
//!
//! Where F vanishes along a side (sin(5x)·y at y = 0), the side's edges have no error and are
//! never split, while vertices above them crowd ever closer: their triangles on the side
//! become needles. Ruppert's refinement splits a boundary edge that a vertex *encroaches*:
//! one whose diametral circle holds it, i.e. that it sees at more than 90°; Shewchuk's
//! diametral lens asks for more than 120°. In a Delaunay mesh the triangle's own apex is the
//! vertex to ask (any vertex in the circle or lens lies inside the circle through the edge and
//! that apex otherwise, which is empty). Which of the two is measured (docs/terrain.md): on
//! midpoints, the lens leaves the smooth functions' meshes as they were (with the circle,
//! sin(10x)·cos(10y) at 10^3 vertices had 7% more error; with the lens none of the quality
//! functions moved by more than 1.2%) and takes sin(5x)·y's smallest angle at 5,000 vertices
//! from 0.06° to 17°; on a DEM's nodes, the circle lowers the max error at every budget
//! measured, where the lens raised it by 11% at 10^3 vertices. With `min_angle`, a triangle
//! whose smallest angle is below it is repaired too, by bisecting the end of its longest-edge
//! path (Rivara's Lepp-Delaunay refinement).
//!
//! A repair is a step like any other (the budget and the tolerance stop a run whatever is left
//! to repair) and goes before any error-driven split. The triangles each step rewrites are
//! looked at, so a repair costs nothing where no triangle needs one.

use crate::geom::{Mesh, NONE, Point};

/// When an apex encroaches its triangle's boundary edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Encroachment {
    /// Never: no flips keep circles empty without `semi-recursive`, and Rivara's bisection
    /// bounds the angles itself.
    Never,
    /// The apex sees the edge at more than 90°: it lies in the diametral circle.
    Circle,
    /// At more than 120°: it lies in the diametral lens.
    Lens,
}

impl Encroachment {
    /// cos² of the angle, or `None` for [`Encroachment::Never`].
    fn cos_sq(self) -> Option<f64> {
        match self {
            Encroachment::Never => None,
            Encroachment::Circle => Some(0.0),
            Encroachment::Lens => Some(LENS_COS_SQ),
        }
    }
}

/// cos² of 120°, the diametral lens's angle.
const LENS_COS_SQ: f64 = 0.25;

/// What a triangle needs, if anything.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Repair {
    /// Split the boundary edge of this half-edge: its apex lies in the edge's lens.
    Encroached(u32),
    /// The triangle's smallest angle is below `min_angle`: bisect the end of its longest-edge
    /// path.
    Skinny,
}

/// Triangles to look at before the next error-driven split.
#[derive(Debug)]
pub(super) struct Repairs {
    /// cos² of the angle above which an apex encroaches its boundary edge, if any does.
    encroachment: Option<f64>,
    /// cos² of `min_angle`, if one is set: an angle below it has a larger cos.
    min_angle_cos_sq: Option<f64>,
    /// Triangles a step rewrote that may need a repair, looked at last first.
    pending: Vec<u32>,
}

impl Repairs {
    /// Repairs of boundary edges their apex encroaches and, with a `min_angle` in degrees, of
    /// triangles with a smaller angle.
    pub(super) fn new(encroachment: Encroachment, min_angle: Option<f64>) -> Self {
        Self {
            encroachment: encroachment.cos_sq(),
            min_angle_cos_sq: min_angle.map(cos_sq_of),
            pending: Vec::new(),
        }
    }

    /// Whether this asks for nothing, so that the loops need not look.
    pub(super) fn is_idle(&self) -> bool {
        self.encroachment.is_none() && self.min_angle_cos_sq.is_none()
    }

    /// Triangles `ts`, just rewritten, may need a repair.
    pub(super) fn look_at(&mut self, ts: &[u32]) {
        if !self.is_idle() {
            self.pending.extend(ts.iter().rev());
        }
    }

    /// The next triangle that needs a repair, and what it needs.
    pub(super) fn next(&mut self, mesh: &Mesh) -> Option<(u32, Repair)> {
        while let Some(t) = self.pending.pop() {
            if let Some(repair) = self.needs(mesh, t) {
                return Some((t, repair));
            }
        }
        None
    }

    /// What triangle `t` needs, if anything: an encroached boundary edge first.
    pub(super) fn needs(&self, mesh: &Mesh, t: u32) -> Option<Repair> {
        let [a, b, c] = mesh.triangle(t as usize).map(|v| mesh.point(v));
        if let Some(cos_sq) = self.encroachment
            && let Some(e) = (3 * t..3 * t + 3).find(|&e| encroached(mesh, e, cos_sq))
        {
            return Some(Repair::Encroached(e));
        }
        // Without a floor the angles are not measured at all.
        let skinny = self.min_angle_cos_sq.is_some_and(|floor| smallest_angle_cos_sq(a, b, c) > floor);
        skinny.then_some(Repair::Skinny)
    }
}

/// How many triangles of `mesh` have an angle below `degrees`, by the test repairs make.
pub(super) fn count_below(mesh: &Mesh, degrees: f64) -> u64 {
    let cos_sq = cos_sq_of(degrees);
    let skinny =
        |&[a, b, c]: &[u32; 3]| smallest_angle_cos_sq(mesh.point(a), mesh.point(b), mesh.point(c)) > cos_sq;
    mesh.triangles().filter(skinny).count() as u64
}

/// cos² of an angle of `degrees`: a triangle whose smallest angle is below it has a larger
/// [`smallest_angle_cos_sq`].
pub(super) fn cos_sq_of(degrees: f64) -> f64 {
    degrees.to_radians().cos().powi(2)
}

/// Whether half-edge `h` lies on the boundary and its apex in its diametral lens.
pub(super) fn lens_encroached(mesh: &Mesh, h: u32) -> bool {
    encroached(mesh, h, LENS_COS_SQ)
}

/// Whether half-edge `h` lies on the boundary and its apex sees it at an angle whose cos² is
/// above `cos_sq`; an interior edge is rejected before any point is read.
fn encroached(mesh: &Mesh, h: u32, cos_sq: f64) -> bool {
    mesh.twin(h) == NONE
        && sees_wider(mesh.point(mesh.origin(h)), mesh.point(mesh.dest(h)), mesh.point(mesh.apex(h)), cos_sq)
}

/// Whether `apex` sees p q at an obtuse angle whose cos² is above `cos_sq`.
fn sees_wider(p: Point, q: Point, apex: Point, cos_sq: f64) -> bool {
    let (u, v) = ((p.x - apex.x, p.y - apex.y), (q.x - apex.x, q.y - apex.y));
    let dot = u.0 * v.0 + u.1 * v.1;
    dot < 0.0 && dot * dot > cos_sq * (u.0 * u.0 + u.1 * u.1) * (v.0 * v.0 + v.1 * v.1)
}

/// cos² of the triangle's smallest angle, the one opposite its shortest edge (law of cosines).
/// Not a topology decision, so plain floating point: the same bits on every machine.
pub(super) fn smallest_angle_cos_sq(a: Point, b: Point, c: Point) -> f64 {
    let (ab, bc, ca) = (a.distance_sq(b), b.distance_sq(c), c.distance_sq(a));
    // The shortest edge and the two that meet opposite it.
    let (short, u, v) = if ab <= bc && ab <= ca {
        (ab, bc, ca)
    } else if bc <= ca {
        (bc, ca, ab)
    } else {
        (ca, ab, bc)
    };
    let cos = u + v - short;
    // cos θ = (u + v − short) / (2√(uv)) ≥ 0 for the smallest angle (at most 60°).
    cos * cos / (4.0 * u * v)
}

/// The half-edge of triangle `t`'s longest edge; among equal lengths, the first.
pub(super) fn longest_edge(mesh: &Mesh, t: u32) -> u32 {
    (3 * t..3 * t + 3).fold(3 * t, |best, e| if mesh.len_sq(e) > mesh.len_sq(best) { e } else { best })
}

/// The end of the longest-edge propagation path from `t`: follow longest edges across
/// neighbours while the neighbour's longest edge is strictly longer. Lengths grow strictly
/// along the path, so it ends; its last edge is the longest edge of both its triangles (or
/// on the boundary), so bisecting it keeps the mesh conforming.
pub(super) fn terminal_edge(mesh: &Mesh, t: u32) -> u32 {
    let mut e = longest_edge(mesh, t);
    loop {
        let f = mesh.twin(e);
        if f == NONE {
            return e;
        }
        let g = longest_edge(mesh, f / 3);
        if mesh.len_sq(g) <= mesh.len_sq(e) {
            return e;
        }
        e = g;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{Rect, Vertex};

    #[test]
    fn the_smallest_angle_is_measured_opposite_the_shortest_edge() {
        let deg = |a: (f64, f64), b: (f64, f64), c: (f64, f64)| {
            let cos_sq =
                smallest_angle_cos_sq(Point::new(a.0, a.1), Point::new(b.0, b.1), Point::new(c.0, c.1));
            cos_sq.sqrt().acos().to_degrees()
        };
        assert!((deg((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)) - 45.0).abs() < 1e-9);
        assert!((deg((0.0, 0.0), (1.0, 0.0), (0.5, 3f64.sqrt() / 2.0)) - 60.0).abs() < 1e-6);
        assert!((deg((0.0, 0.0), (10.0, 0.0), (10.0, 1.0)) - 1f64.atan2(10.0).to_degrees()).abs() < 1e-9);
    }

    #[test]
    fn a_vertex_over_a_boundary_edge_encroaches_it_and_a_right_angle_does_not() {
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let repairs = Repairs::new(Encroachment::Lens, None);
        // S4's corners see the sides at 90°, outside their lenses.
        assert_eq!(repairs.needs(&mesh, 0), None);
        // (0.9, 0.1) inside P1 P2 P3, near P2, sees P1P2 and P2P3 at 129°.
        let split = mesh.insert_inside(0, Vertex { x: 0.9, y: 0.1, z: 0.0 });
        let encroached: Vec<(u32, u32)> = split
            .link()
            .iter()
            .filter_map(|&e| match repairs.needs(&mesh, e / 3) {
                Some(Repair::Encroached(h)) => Some((mesh.origin(h), mesh.dest(h))),
                _ => None,
            })
            .collect();
        assert_eq!(encroached, [(0, 1), (1, 2)], "P1P2 and P2P3 both");
        assert_eq!(Repairs::new(Encroachment::Never, None).needs(&mesh, split.link()[0] / 3), None);
        // (0.5, 0.3) sees P1P2 at 118°: inside the circle, outside the lens.
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let split = mesh.insert_inside(0, Vertex { x: 0.5, y: 0.3, z: 0.0 });
        let bottom = split.link()[0];
        assert_eq!(repairs.needs(&mesh, bottom / 3), None);
        let circle = Repairs::new(Encroachment::Circle, None);
        assert_eq!(circle.needs(&mesh, bottom / 3), Some(Repair::Encroached(bottom)));
    }

    #[test]
    fn triangles_below_min_angle_are_skinny_and_counted() {
        let mut mesh = Mesh::new(Rect::new(0.0, 10.0, 0.0, 1.0).unwrap(), [0.0; 4]);
        // Both halves of a 10 × 1 rectangle have a smallest angle of 5.7°.
        assert_eq!(Repairs::new(Encroachment::Never, Some(5.0)).needs(&mesh, 0), None);
        assert_eq!(Repairs::new(Encroachment::Never, Some(6.0)).needs(&mesh, 0), Some(Repair::Skinny));
        assert_eq!(count_below(&mesh, 6.0), 2);
        assert_eq!(count_below(&mesh, 5.0), 0);
        assert!(
            Repairs::new(Encroachment::Never, None).is_idle()
                && !Repairs::new(Encroachment::Never, Some(1.0)).is_idle()
        );
        let mut repairs = Repairs::new(Encroachment::Never, Some(6.0));
        repairs.look_at(&[1, 0]);
        assert_eq!(repairs.next(&mesh), Some((1, Repair::Skinny)));
        let split = mesh.split(mesh.find_edge(0, 2).unwrap(), Vertex { x: 5.0, y: 0.5, z: 0.0 });
        assert_eq!(split.vertex, 4);
        assert!(repairs.next(&mesh).is_some());
        assert_eq!(repairs.next(&mesh), None);
    }
}
