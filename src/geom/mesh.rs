//! The triangle mesh: flat arrays of vertices, triangle corners and half-edge twins.
//!
//! Triangle `t` owns half-edges `3t`, `3t + 1` and `3t + 2`; half-edge `e` runs from
//! `half[e].origin` to the origin of `next(e)`, with the triangle on its left. `half[e].twin`
//! is the half-edge running the other way in the neighbouring triangle, or [`NONE`] on the
//! boundary. This is the layout of delaunator and hmm (no pointers, every topology query is
//! index arithmetic) with origin and twin side by side: a triangle's 24 bytes are read
//! together, so a walk or a flip touches one cache line per triangle instead of two.

use super::constraints::Constraints;
use super::{Point, Rect, Vertex};

/// The missing twin of a boundary half-edge.
pub const NONE: u32 = u32::MAX;

/// The half-edge after `e` in its triangle (counter-clockwise).
#[inline]
pub const fn next(e: u32) -> u32 {
    if e % 3 == 2 { e - 2 } else { e + 1 }
}

/// The half-edge before `e` in its triangle.
#[inline]
pub const fn prev(e: u32) -> u32 {
    if e.is_multiple_of(3) { e + 2 } else { e - 1 }
}

/// One half-edge's slot: the vertex it leaves and its twin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct HalfEdge {
    /// The vertex the half-edge leaves.
    pub(super) origin: u32,
    /// The opposite half-edge, or [`NONE`].
    pub(super) twin: u32,
}

/// An undirected mesh edge between vertices `a` and `b`, with one of its half-edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// The origin of `halfedge`.
    pub a: u32,
    /// The destination of `halfedge`.
    pub b: u32,
    /// A half-edge from `a` to `b`; for a boundary edge the only one.
    pub halfedge: u32,
}

/// A conforming triangulation of a rectangle whose vertices carry values of F.
///
/// Vertex ids are dense and in insertion order, so any prefix of [`Mesh::vertices`] is the
/// vertex set at an earlier step. Every triangle is counter-clockwise.
#[derive(Debug, Clone)]
pub struct Mesh {
    pub(super) rect: Rect,
    pub(super) vertices: Vec<Vertex>,
    /// Origin and twin of each half-edge.
    pub(super) half: Vec<HalfEdge>,
    /// One half-edge leaving each vertex, the entry point for walks around it.
    pub(super) outgoing: Vec<u32>,
    /// Interior edges that splits keep and flips never take (regions' sides).
    pub(super) constraints: Constraints,
}

impl Mesh {
    /// The primary mesh S₄: corners P1..P4 (ids 0..3) with values `z`, triangles P1P2P3 and
    /// P1P3P4 (diagonal P1P3).
    ///
    /// ```
    /// use meshfit::geom::{Mesh, Rect};
    /// let mesh = Mesh::new(Rect::unit(), [0.0, 1.0, 2.0, 3.0]);
    /// assert_eq!(mesh.triangle(0), [0, 1, 2]);
    /// assert_eq!(mesh.triangle(1), [0, 2, 3]);
    /// ```
    pub fn new(rect: Rect, z: [f64; 4]) -> Self {
        Self::with_capacity(rect, z, 4)
    }

    /// [`Mesh::new`] with room for `vertices` vertices, so that refinement to that size does
    /// not reallocate.
    pub fn with_capacity(rect: Rect, z: [f64; 4], vertices: usize) -> Self {
        let vertices = vertices.max(4);
        // A triangulation of n points has at most 2n - 5 triangles when n >= 4 (h >= 3).
        let half_edges = 3 * (2 * vertices);
        let mut mesh = Self {
            rect,
            vertices: Vec::with_capacity(vertices),
            half: Vec::with_capacity(half_edges),
            outgoing: Vec::with_capacity(vertices),
            constraints: Constraints::default(),
        };
        for (p, z) in rect.corners().into_iter().zip(z) {
            mesh.vertices.push(Vertex { x: p.x, y: p.y, z });
        }
        let s4 = [(0, NONE), (1, NONE), (2, 3), (0, 2), (2, NONE), (3, NONE)];
        mesh.half.extend(s4.map(|(origin, twin)| HalfEdge { origin, twin }));
        mesh.outgoing.extend_from_slice(&[0, 1, 4, 5]);
        mesh
    }

    /// The rectangle the mesh covers.
    pub fn rect(&self) -> Rect {
        self.rect
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.half.len() / 3
    }

    /// Number of half-edge slots (3 per triangle).
    pub fn num_halfedges(&self) -> usize {
        self.half.len()
    }

    /// All vertices in insertion order.
    pub fn vertices(&self) -> &[Vertex] {
        &self.vertices
    }

    /// Vertex `v`.
    #[inline]
    pub fn vertex(&self, v: u32) -> Vertex {
        self.vertices[v as usize]
    }

    /// Sets every vertex's z, in vertex order: a boundary value problem's new solution on
    /// the same vertices. Positions and topology are untouched.
    ///
    /// # Panics
    /// When `z` does not have one value per vertex.
    pub fn set_values(&mut self, z: &[f64]) {
        assert_eq!(z.len(), self.vertices.len(), "one value per vertex");
        for (v, &z) in self.vertices.iter_mut().zip(z) {
            v.z = z;
        }
    }

    /// Position of vertex `v`.
    #[inline]
    pub fn point(&self, v: u32) -> Point {
        self.vertices[v as usize].point()
    }

    /// The corners of triangle `t`, counter-clockwise.
    #[inline]
    pub fn triangle(&self, t: usize) -> [u32; 3] {
        [self.half[3 * t].origin, self.half[3 * t + 1].origin, self.half[3 * t + 2].origin]
    }

    /// All triangles, each as its counter-clockwise corners.
    pub fn triangles(&self) -> impl ExactSizeIterator<Item = [u32; 3]> + '_ {
        self.half.chunks_exact(3).map(|c| [c[0].origin, c[1].origin, c[2].origin])
    }

    /// The vertex half-edge `e` leaves.
    #[inline]
    pub fn origin(&self, e: u32) -> u32 {
        self.half[e as usize].origin
    }

    /// The vertex half-edge `e` enters.
    #[inline]
    pub fn dest(&self, e: u32) -> u32 {
        self.half[next(e) as usize].origin
    }

    /// The corner of `e`'s triangle opposite `e`.
    #[inline]
    pub fn apex(&self, e: u32) -> u32 {
        self.half[prev(e) as usize].origin
    }

    /// The squared length of `e`'s edge.
    #[inline]
    pub fn len_sq(&self, e: u32) -> f64 {
        self.point(self.origin(e)).distance_sq(self.point(self.dest(e)))
    }

    /// The twin of `e`, or [`NONE`] when `e` is on the boundary.
    #[inline]
    pub fn twin(&self, e: u32) -> u32 {
        self.half[e as usize].twin
    }

    /// Every undirected edge once, in half-edge order.
    pub fn edges(&self) -> impl Iterator<Item = Edge> + '_ {
        (0..self.half.len() as u32).filter_map(move |e| {
            let t = self.half[e as usize].twin;
            (t == NONE || e < t).then(|| Edge { a: self.origin(e), b: self.dest(e), halfedge: e })
        })
    }

    /// Number of undirected edges.
    pub fn num_edges(&self) -> usize {
        (self.half.len() + self.num_boundary_vertices()) / 2
    }

    /// Number of vertices on the rectangle's boundary (h in triangles = 2n − h − 2).
    pub fn num_boundary_vertices(&self) -> usize {
        // Every boundary vertex starts exactly one boundary half-edge.
        self.half.iter().filter(|h| h.twin == NONE).count()
    }

    /// A half-edge between `a` and `b` in either direction, if the edge exists.
    pub fn find_edge(&self, a: u32, b: u32) -> Option<u32> {
        self.walk_around(a, |neighbour, _| neighbour == b)
    }

    /// The half-edge [`Mesh::find_edge`] gives for (a, b), from half-edge `h` alone when `h`
    /// lies on that edge: `h` when it runs a → b, else its twin, or `h` itself on the boundary
    /// (the walk finds a → b where it exists). `None` when `h` lies on another edge, which
    /// says nothing of (a, b): a flip may have moved it to another slot.
    #[inline]
    pub fn edge_at(&self, h: u32, a: u32, b: u32) -> Option<u32> {
        let (p, q) = (self.origin(h), self.dest(h));
        if (p, q) == (a, b) {
            Some(h)
        } else if (p, q) == (b, a) {
            let twin = self.twin(h);
            Some(if twin == NONE { h } else { twin })
        } else {
            None
        }
    }

    /// Calls `f(neighbour, halfedge)` for every vertex joined to `v` by an edge, where
    /// `halfedge` is a half-edge of that edge.
    pub fn for_each_neighbour(&self, v: u32, mut f: impl FnMut(u32, u32)) {
        self.walk_around(v, |n, e| {
            f(n, e);
            false
        });
    }

    /// Walks the fan of triangles around `v` and returns the first half-edge for which
    /// `stop(neighbour, halfedge)` holds. Each neighbour is visited once.
    fn walk_around(&self, v: u32, mut stop: impl FnMut(u32, u32) -> bool) -> Option<u32> {
        let start = self.outgoing[v as usize];
        debug_assert_eq!(self.origin(start), v);
        // Counter-clockwise: from v→w to the edge v→u entering v in the same triangle.
        let mut e = start;
        loop {
            if stop(self.dest(e), e) {
                return Some(e);
            }
            let incoming = prev(e);
            let t = self.half[incoming as usize].twin;
            if t == NONE {
                // Boundary reached: its edge is seen only as entering v.
                if stop(self.origin(incoming), incoming) {
                    return Some(incoming);
                }
                break;
            }
            e = t;
            if e == start {
                return None;
            }
        }
        // The fan is open: walk clockwise from the start to the other boundary edge.
        let mut e = start;
        loop {
            let t = self.half[e as usize].twin;
            if t == NONE {
                return None;
            }
            e = next(t);
            if stop(self.dest(e), e) {
                return Some(e);
            }
        }
    }

    /// Re-points `outgoing` of the corners of triangle `t` at `t`'s own half-edges; called
    /// after every rewrite so walks always start from a live half-edge.
    #[inline]
    pub(super) fn claim_corners(&mut self, t: u32) {
        for e in 3 * t..3 * t + 3 {
            self.outgoing[self.half[e as usize].origin as usize] = e;
        }
    }

    /// Writes triangle `t` as (p, q, r) with the given twins of its three half-edges, and
    /// makes those twins point back.
    #[inline]
    pub(super) fn set_triangle(&mut self, t: u32, [p, q, r]: [u32; 3], twins: [u32; 3]) {
        for (k, (origin, twin)) in [p, q, r].into_iter().zip(twins).enumerate() {
            let e = 3 * t + k as u32;
            self.half[e as usize].origin = origin;
            self.link(e, twin);
        }
    }

    /// Makes `a` and `b` twins (or marks `a` as boundary when `b` is [`NONE`]).
    #[inline]
    pub(super) fn link(&mut self, a: u32, b: u32) {
        self.half[a as usize].twin = b;
        if b != NONE {
            self.half[b as usize].twin = a;
        }
    }

    /// Appends an uninitialised triangle slot and returns its index.
    #[inline]
    pub(super) fn push_triangle(&mut self) -> u32 {
        let t = self.num_triangles() as u32;
        self.half.extend_from_slice(&[HalfEdge { origin: NONE, twin: NONE }; 3]);
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primary_mesh_has_four_corners_two_triangles_and_five_edges() {
        let mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        mesh.check_invariants().unwrap();
        assert_eq!(mesh.num_vertices(), 4);
        assert_eq!(mesh.num_triangles(), 2);
        assert_eq!(mesh.num_edges(), 5);
        assert_eq!(mesh.num_boundary_vertices(), 4);
        // The only interior edge is the diagonal P1P3.
        let interior: Vec<_> = mesh.edges().filter(|e| mesh.twin(e.halfedge) != NONE).collect();
        assert_eq!(interior.len(), 1);
        assert_eq!((interior[0].a.min(interior[0].b), interior[0].a.max(interior[0].b)), (0, 2));
    }

    #[test]
    fn walks_find_every_neighbour_of_boundary_and_corner_vertices() {
        let mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let mut around_p1 = Vec::new();
        mesh.for_each_neighbour(0, |n, _| around_p1.push(n));
        around_p1.sort_unstable();
        assert_eq!(around_p1, [1, 2, 3]);
        let mut around_p2 = Vec::new();
        mesh.for_each_neighbour(1, |n, _| around_p2.push(n));
        around_p2.sort_unstable();
        assert_eq!(around_p2, [0, 2]);
        assert!(mesh.find_edge(1, 3).is_none());
        let e = mesh.find_edge(3, 1);
        assert!(e.is_none());
        let e = mesh.find_edge(2, 0).unwrap();
        assert_eq!([mesh.origin(e).min(mesh.dest(e)), mesh.origin(e).max(mesh.dest(e))], [0, 2]);
    }
}
