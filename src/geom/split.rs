//! Splitting an edge at a new vertex: 2 → 4 triangles inside, 1 → 2 on the boundary.

use super::mesh::{Mesh, NONE, next, prev};
use super::predicates::{Orientation, orientation, signed_area_x2};
use super::{Point, Vertex};

/// What a split changed: the new vertex and the half-edges of its link (the edges opposite
/// it), which are the only candidates for a Delaunay flip afterwards.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Split {
    /// Id of the inserted vertex.
    pub vertex: u32,
    /// Half-edges opposite the new vertex; only the first [`Split::link_len`] are used.
    pub link: [u32; 4],
    /// 4 for an interior edge, 2 for a boundary edge.
    pub link_len: usize,
    /// Whether the new vertex lies exactly on the split edge (exact `orient2d`); a rounded
    /// midpoint of a slanted edge may not.
    pub on_edge: bool,
}

impl Split {
    /// The used part of [`Split::link`].
    pub fn link(&self) -> &[u32] {
        &self.link[..self.link_len]
    }

    /// Every half-edge of the new triangles that has a twin candidate: the link edges and the
    /// spokes from the new vertex, for [`Mesh::legalize_all`].
    pub fn suspects(&self) -> impl Iterator<Item = u32> + '_ {
        self.link().iter().flat_map(|&e| [e, e + 1, e + 2])
    }
}

/// Whether `m` lies exactly on the line through `a` and `b`.
///
/// Midpoints of dyadic meshes are almost always exact: when both coordinate sums are free of
/// rounding (checked by Knuth's TwoSum, whose error term is exact), `m` is the true midpoint.
/// Only otherwise is the exact `orient2d` asked, whose adaptive path a collinear input always
/// takes.
fn is_on_segment_line(a: Point, b: Point, m: Point) -> bool {
    let exact_sum = |p: f64, q: f64| {
        let s = p + q;
        let q_virtual = s - p;
        (p - (s - q_virtual)) + (q - q_virtual) == 0.0
    };
    let is_midpoint = exact_sum(a.x, b.x) && exact_sum(a.y, b.y) && m == a.midpoint(b);
    is_midpoint || orientation(a, b, m) == Orientation::Collinear
}

impl Mesh {
    /// Whether splitting the edge of half-edge `e` at `m` gives new triangles that are all
    /// strictly counter-clockwise (decided exactly) with twice their area above `min_area_x2`.
    ///
    /// A rounded midpoint of an interior edge may sit a hair off the edge; this rejects the
    /// splits where that would fold or flatten a triangle, and a midpoint that rounded onto an
    /// endpoint. The area floor stops slivers from creeping toward a line: without it, repeated
    /// splits of the long edges of flat triangles along the boundary drive vertices to within
    /// subnormal distances of it, where even exact predicates lose their guarantees.
    pub fn can_split(&self, e: u32, m: Point, min_area_x2: f64) -> bool {
        let ok = |p, q| {
            let area = signed_area_x2(p, q, m);
            area > 0.0 && area > min_area_x2
        };
        let a = self.point(self.origin(e));
        let b = self.point(self.dest(e));
        let c = self.point(self.apex(e));
        if !(ok(c, a) && ok(b, c)) {
            return false;
        }
        let f = self.twin(e);
        f == NONE || {
            let d = self.point(self.apex(f));
            ok(a, d) && ok(d, b)
        }
    }

    /// Inserts `m` on the edge of half-edge `e`, splitting the one or two triangles beside it.
    ///
    /// ```text
    ///  interior edge a→b (e), twin b→a (f)        boundary edge a→b (e)
    ///
    ///         c                  c                      c              c
    ///        / \                /|\                    / \            /|\
    ///       / t0\             t0 | t2                 / t0\         t0 | t2
    ///      a-----b    ==>     a--m--b                a-----b  ==>   a--m--b
    ///       \ t1/             t1 | t3
    ///        \ /                \|/
    ///         d                  d
    /// ```
    /// t0 = (c, a, m), t2 = (b, c, m) new, t1 = (a, d, m), t3 = (d, b, m) new: every new
    /// triangle has the new vertex last, so its half-edge 0 is the link edge opposite `m`.
    /// Old vertices keep their ids and every edge other than a→b survives.
    ///
    /// # Panics
    /// In debug builds, when [`Mesh::can_split`] would have refused.
    pub fn split(&mut self, e: u32, m: Vertex) -> Split {
        debug_assert!(self.can_split(e, m.point(), 0.0), "split would create a non-positive triangle");
        let (a, b, c) = (self.origin(e), self.dest(e), self.apex(e));
        let on_edge = is_on_segment_line(self.point(a), self.point(b), m.point());
        let t0 = e / 3;
        let (out_bc, out_ca) = (self.twin(next(e)), self.twin(prev(e)));
        let f = self.twin(e);
        let mv = self.vertices.len() as u32;
        self.vertices.push(m);
        self.outgoing.push(NONE);
        let t2 = self.push_triangle();

        if f == NONE {
            self.set_triangle(t0, [c, a, mv], [out_ca, NONE, 3 * t2 + 1]);
            self.set_triangle(t2, [b, c, mv], [out_bc, 3 * t0 + 2, NONE]);
            self.claim_corners(t0);
            self.claim_corners(t2);
            return Split { vertex: mv, link: [3 * t0, 3 * t2, NONE, NONE], link_len: 2, on_edge };
        }

        let d = self.apex(f);
        let t1 = f / 3;
        let (out_ad, out_db) = (self.twin(next(f)), self.twin(prev(f)));
        let t3 = self.push_triangle();
        self.set_triangle(t0, [c, a, mv], [out_ca, 3 * t1 + 2, 3 * t2 + 1]);
        self.set_triangle(t2, [b, c, mv], [out_bc, 3 * t0 + 2, 3 * t3 + 1]);
        self.set_triangle(t1, [a, d, mv], [out_ad, 3 * t3 + 2, 3 * t0 + 1]);
        self.set_triangle(t3, [d, b, mv], [out_db, 3 * t2 + 2, 3 * t1 + 1]);
        for t in [t0, t1, t2, t3] {
            self.claim_corners(t);
        }
        Split { vertex: mv, link: [3 * t0, 3 * t2, 3 * t1, 3 * t3], link_len: 4, on_edge }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Rect;

    fn centre(mesh: &Mesh, e: u32, z: f64) -> Vertex {
        let p = mesh.point(mesh.origin(e)).midpoint(mesh.point(mesh.dest(e)));
        Vertex { x: p.x, y: p.y, z }
    }

    #[test]
    fn interior_split_adds_one_vertex_two_triangles_and_three_edges() {
        // S4 with the diagonal P1P3 split at the centre: 4 triangles around (0.5, 0.5).
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let diagonal = mesh.find_edge(0, 2).unwrap();
        let m = centre(&mesh, diagonal, 1.0);
        let split = mesh.split(diagonal, m);
        mesh.check_invariants().unwrap();
        assert_eq!(split.vertex, 4);
        assert_eq!(split.link_len, 4);
        assert_eq!(mesh.num_triangles(), 4);
        // 5 old edges − 1 split + 2 halves + 2 new edges.
        assert_eq!(mesh.num_edges(), 8);
        assert!(mesh.find_edge(0, 2).is_none());
        for v in 0..4 {
            assert!(mesh.find_edge(4, v).is_some(), "centre not joined to corner {v}");
        }
        for &e in split.link() {
            assert_eq!(mesh.apex(e), 4, "link half-edge {e} is not opposite the new vertex");
        }
    }

    #[test]
    fn boundary_split_adds_one_vertex_one_triangle_and_two_edges() {
        // S4 with P1P2 split at P5 = (0.5, 0): 3 triangles.
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let bottom = mesh.find_edge(0, 1).unwrap();
        let split = mesh.split(bottom, centre(&mesh, bottom, 0.0));
        mesh.check_invariants().unwrap();
        assert_eq!(split.link_len, 2);
        assert_eq!(mesh.num_triangles(), 3);
        // 5 old edges − 1 split + 2 halves + 1 new edge.
        assert_eq!(mesh.num_edges(), 7);
        assert_eq!(mesh.point(4), Point::new(0.5, 0.0));
        assert!(mesh.find_edge(4, 2).is_some());
        assert!(mesh.find_edge(4, 3).is_none());
        assert!(mesh.find_edge(0, 2).is_some());
    }

    #[test]
    fn split_is_refused_when_the_point_is_not_strictly_inside_the_quadrilateral() {
        let mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let diagonal = mesh.find_edge(0, 2).unwrap();
        // An endpoint, a point outside, and a point on the far side of a link edge.
        assert!(!mesh.can_split(diagonal, Point::new(0.0, 0.0), 0.0));
        assert!(!mesh.can_split(diagonal, Point::new(2.0, 2.0), 0.0));
        assert!(!mesh.can_split(diagonal, Point::new(1.0, 0.5), 0.0));
        assert!(mesh.can_split(diagonal, Point::new(0.5, 0.5), 0.0));
        // Each of the four triangles around the centre has twice-area 0.5.
        assert!(mesh.can_split(diagonal, Point::new(0.5, 0.5), 0.49));
        assert!(!mesh.can_split(diagonal, Point::new(0.5, 0.5), 0.5));
    }
}

#[cfg(test)]
mod properties {
    use crate::geom::{Mesh, Rect, Vertex};
    use proptest::prelude::*;

    proptest! {
        /// Any sequence of midpoint splits, with or without flips, leaves a valid mesh whose
        /// edge count grows by 2 (boundary) or 3 (interior) per split, and Lawson flips after
        /// each split keep it Delaunay.
        #[test]
        fn any_sequence_of_splits_leaves_the_mesh_valid(
            picks in prop::collection::vec(any::<u32>(), 1..150),
            flip in any::<bool>(),
            (a, w, c, h) in (-10.0..10.0f64, 0.1..10.0f64, -10.0..10.0f64, 0.1..10.0f64),
        ) {
            let mut mesh = Mesh::new(Rect::new(a, a + w, c, c + h).unwrap(), [0.0; 4]);
            let mut stack = Vec::new();
            for pick in picks {
                let e = pick % mesh.num_halfedges() as u32;
                let m = mesh.point(mesh.origin(e)).midpoint(mesh.point(mesh.dest(e)));
                if !mesh.can_split(e, m, 0.0) {
                    continue;
                }
                let (edges, boundary) = (mesh.num_edges(), mesh.twin(e) == super::NONE);
                let split = mesh.split(e, Vertex { x: m.x, y: m.y, z: 0.0 });
                prop_assert_eq!(mesh.num_edges(), edges + if boundary { 2 } else { 3 });
                if flip {
                    if split.on_edge {
                        stack.extend_from_slice(split.link());
                        mesh.legalize(&mut stack, |_, _| {});
                    } else {
                        stack.extend(split.suspects());
                        mesh.legalize_all(&mut stack, |_, _| {});
                    }
                    prop_assert!(mesh.is_delaunay(), "not Delaunay after inserting {}", split.vertex);
                }
                if let Err(err) = mesh.check_invariants() {
                    prop_assert!(false, "after inserting {}: {}", split.vertex, err);
                }
            }
        }
    }
}
