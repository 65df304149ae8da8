//! Inserting a vertex: on an edge, 2 → 4 triangles inside and 1 → 2 on the boundary; inside a
//! triangle, 1 → 3.

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
    /// 4 for an interior edge, 2 for a boundary edge, 3 for a vertex inside a triangle.
    pub link_len: usize,
    /// Whether the new vertex lies exactly on the split edge or inside the split triangle
    /// (exact `orient2d`), so that only link edges can be illegal afterwards; a rounded
    /// midpoint of a slanted edge may sit a hair off its edge.
    pub exact: bool,
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
        let exact = is_on_segment_line(self.point(a), self.point(b), m.point());
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
            return Split { vertex: mv, link: [3 * t0, 3 * t2, NONE, NONE], link_len: 2, exact };
        }

        let d = self.apex(f);
        self.constraints.split(a, b, mv);
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
        Split { vertex: mv, link: [3 * t0, 3 * t2, 3 * t1, 3 * t3], link_len: 4, exact }
    }

    /// Whether inserting `m` inside triangle `t` gives three triangles that are all strictly
    /// counter-clockwise (decided exactly) with twice their area above `min_area_x2`: `m` lies
    /// strictly inside, and not within the floor of an edge.
    pub fn can_insert_inside(&self, t: u32, m: Point, min_area_x2: f64) -> bool {
        let [a, b, c] = self.triangle(t as usize).map(|v| self.point(v));
        [(a, b), (b, c), (c, a)].into_iter().all(|(p, q)| {
            let area = signed_area_x2(p, q, m);
            area > 0.0 && area > min_area_x2
        })
    }

    /// Inserts `m` strictly inside triangle `t`, joining it to the three corners.
    ///
    /// ```text
    ///          c                   c
    ///         / \                 /|\
    ///        /   \               / | \
    ///       /  t  \     ==>     /t2|t1\
    ///      /       \           /  _m_  \
    ///     a---------b         a--- t0 --b
    /// ```
    /// t0 = (a, b, m) keeps `t`'s slot, t1 = (b, c, m) and t2 = (c, a, m) are new: as in
    /// [`Mesh::split`], the new vertex comes last, so each new triangle's half-edge 0 is the
    /// link edge opposite `m`. Every old edge survives.
    ///
    /// # Panics
    /// In debug builds, when [`Mesh::can_insert_inside`] would have refused.
    pub fn insert_inside(&mut self, t: u32, m: Vertex) -> Split {
        debug_assert!(self.can_insert_inside(t, m.point(), 0.0), "the vertex is not strictly inside");
        let [a, b, c] = self.triangle(t as usize);
        let [out_ab, out_bc, out_ca] = [0, 1, 2].map(|k| self.twin(3 * t + k));
        let mv = self.vertices.len() as u32;
        self.vertices.push(m);
        self.outgoing.push(NONE);
        let (t0, t1, t2) = (t, self.push_triangle(), self.push_triangle());
        self.set_triangle(t0, [a, b, mv], [out_ab, 3 * t1 + 2, 3 * t2 + 1]);
        self.set_triangle(t1, [b, c, mv], [out_bc, 3 * t2 + 2, 3 * t0 + 1]);
        self.set_triangle(t2, [c, a, mv], [out_ca, 3 * t0 + 2, 3 * t1 + 1]);
        for t in [t0, t1, t2] {
            self.claim_corners(t);
        }
        Split { vertex: mv, link: [3 * t0, 3 * t1, 3 * t2, NONE], link_len: 3, exact: true }
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
    fn inside_insertion_adds_one_vertex_two_triangles_and_three_edges() {
        // Triangle 0 of S4 is P1 P2 P3; (0.75, 0.25) lies strictly inside it.
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        assert!(mesh.can_insert_inside(0, Point::new(0.75, 0.25), 0.0));
        let split = mesh.insert_inside(0, Vertex { x: 0.75, y: 0.25, z: 2.0 });
        mesh.check_invariants().unwrap();
        assert_eq!((split.vertex, split.link_len, split.exact), (4, 3, true));
        assert_eq!(mesh.num_triangles(), 4);
        // 5 old edges, all kept, + 3 spokes.
        assert_eq!(mesh.num_edges(), 8);
        for v in [0, 1, 2] {
            assert!(mesh.find_edge(4, v).is_some(), "no spoke to corner {v}");
        }
        assert!(mesh.find_edge(4, 3).is_none() && mesh.find_edge(0, 2).is_some());
        for &e in split.link() {
            assert_eq!(mesh.apex(e), 4, "link half-edge {e} is not opposite the new vertex");
        }
    }

    #[test]
    fn inside_insertion_is_refused_on_an_edge_outside_or_under_the_floor() {
        let mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        // On the diagonal, on the bottom side, a corner, and a point of the other triangle.
        for p in [(0.5, 0.5), (0.5, 0.0), (1.0, 0.0), (0.25, 0.75)] {
            assert!(!mesh.can_insert_inside(0, Point::new(p.0, p.1), 0.0), "{p:?}");
        }
        // (0.75, 0.25) makes triangles of twice-area 0.25, 0.25 and 0.5.
        assert!(mesh.can_insert_inside(0, Point::new(0.75, 0.25), 0.24));
        assert!(!mesh.can_insert_inside(0, Point::new(0.75, 0.25), 0.25));
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
        /// Any sequence of midpoint splits and insertions inside triangles, with or without
        /// flips, leaves a valid mesh whose edge count grows by 2 (boundary split) or 3
        /// (interior split, inside insertion) per step, and Lawson flips after each step keep
        /// it Delaunay; `edge_at` agrees with the walk on every half-edge of the result.
        #[test]
        fn any_sequence_of_splits_leaves_the_mesh_valid(
            picks in prop::collection::vec((any::<u32>(), prop::option::of((1u8..15, 1u8..15))), 1..150),
            flip in any::<bool>(),
            (a, w, c, h) in (-10.0..10.0f64, 0.1..10.0f64, -10.0..10.0f64, 0.1..10.0f64),
        ) {
            let mut mesh = Mesh::new(Rect::new(a, a + w, c, c + h).unwrap(), [0.0; 4]);
            let mut stack = Vec::new();
            for (pick, inside) in picks {
                let e = pick % mesh.num_halfedges() as u32;
                let edges = mesh.num_edges();
                let split = match inside {
                    // Barycentric weights (u, w, 16 − u − w) / 16 of the triangle's corners.
                    Some((u, w)) if u + w < 16 => {
                        let [a, b, c] = mesh.triangle((e / 3) as usize).map(|v| mesh.point(v));
                        let (u, w) = (f64::from(u) / 16.0, f64::from(w) / 16.0);
                        let m = Vertex { x: u * a.x + w * b.x + (1.0 - u - w) * c.x, y: u * a.y + w * b.y + (1.0 - u - w) * c.y, z: 0.0 };
                        if !mesh.can_insert_inside(e / 3, m.point(), 0.0) {
                            continue;
                        }
                        let split = mesh.insert_inside(e / 3, m);
                        prop_assert_eq!(mesh.num_edges(), edges + 3);
                        split
                    }
                    _ => {
                        let m = mesh.point(mesh.origin(e)).midpoint(mesh.point(mesh.dest(e)));
                        if !mesh.can_split(e, m, 0.0) {
                            continue;
                        }
                        let boundary = mesh.twin(e) == super::NONE;
                        let split = mesh.split(e, Vertex { x: m.x, y: m.y, z: 0.0 });
                        prop_assert_eq!(mesh.num_edges(), edges + if boundary { 2 } else { 3 });
                        split
                    }
                };
                if flip {
                    if split.exact {
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
            // A half-edge on (a, b) gives the half-edge the walk gives, in either order; one
            // on another edge gives nothing.
            for h in 0..mesh.num_halfedges() as u32 {
                let (p, q) = (mesh.origin(h), mesh.dest(h));
                prop_assert_eq!(mesh.edge_at(h, p, q), mesh.find_edge(p, q));
                prop_assert_eq!(mesh.edge_at(h, q, p), mesh.find_edge(q, p));
                let other = (q + 1) % mesh.num_vertices() as u32;
                if other != p {
                    prop_assert_eq!(mesh.edge_at(h, p, other), None);
                }
            }
        }
    }
}
