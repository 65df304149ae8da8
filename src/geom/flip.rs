//! Lawson flips that restore the Delaunay property around a new vertex.

use super::mesh::{Mesh, NONE, next, prev};
use super::predicates::is_in_circle;

impl Mesh {
    /// Flips the edge of half-edge `e` (u→v, apex m) with its twin (v→u, apex w) and returns
    /// the two new half-edges opposite m: u→w and w→v.
    ///
    /// ```text
    ///         m                 m
    ///        / \               /|\
    ///       / t0\             / | \
    ///      u-----v    ==>    u t0|t1 v
    ///       \ t1/             \ | /
    ///        \ /               \|/
    ///         w                 w
    /// ```
    /// t0 = (u, w, m) and t1 = (w, v, m); the caller guarantees the quadrilateral u w v m is
    /// strictly convex (an in-circle violation implies it).
    pub(crate) fn flip(&mut self, e: u32) -> [u32; 2] {
        let f = self.twin(e);
        debug_assert_ne!(f, NONE, "flip of a boundary edge");
        let [first, second] = self.flipped(e);
        let (out_vm, out_mu) = (self.twin(next(e)), self.twin(prev(e)));
        let (out_uw, out_wv) = (self.twin(next(f)), self.twin(prev(f)));
        let (t0, t1) = (e / 3, f / 3);
        self.set_triangle(t0, first, [out_uw, 3 * t1 + 2, out_mu]);
        self.set_triangle(t1, second, [out_wv, out_vm, 3 * t0 + 1]);
        self.claim_corners(t0);
        self.claim_corners(t1);
        debug_assert!(
            [first, second].iter().all(|t| super::predicates::is_ccw(
                self.point(t[0]),
                self.point(t[1]),
                self.point(t[2])
            )),
            "flip produced a non-CCW triangle"
        );
        [3 * t0, 3 * t1]
    }

    /// The corners of the two triangles [`Mesh::flip`] makes of `e`'s two, in the order
    /// [`Mesh::triangle`] then lists them: (u, w, m) and (w, v, m).
    #[inline]
    pub(crate) fn flipped(&self, e: u32) -> [[u32; 3]; 2] {
        let (u, v, m, w) = (self.origin(e), self.dest(e), self.apex(e), self.apex(self.twin(e)));
        [[u, w, m], [w, v, m]]
    }

    /// Lawson's algorithm after inserting a vertex *exactly* on an edge or inside a triangle:
    /// `stack` holds the half-edges opposite the new vertex; each whose far vertex lies
    /// strictly inside the circumcircle is flipped, and the two edges that then face the new
    /// vertex are checked in turn. Returns the number of flips.
    ///
    /// That only link edges can be illegal relies on the new vertex lying inside the
    /// circumcircles of the triangles it split; a rounded midpoint a hair off its edge may
    /// not, and needs [`Mesh::legalize_all`].
    ///
    /// `stack` is the caller's scratch space, so the hot loop does not allocate; it is empty on
    /// return. `on_flip` is told the half-edge of each new diagonal (its two triangles are the
    /// ones the flip rewrote).
    pub fn legalize(&mut self, stack: &mut Vec<u32>, on_flip: impl FnMut(&Self, u32)) -> u32 {
        self.lawson::<false>(stack, on_flip)
    }

    /// Lawson's algorithm for any set of suspect edges: `stack` holds half-edges that may be
    /// illegal; every flip puts the four outer edges of its quadrilateral on the stack. Ends
    /// with a Delaunay mesh when every edge not on the stack was legal, because each flip
    /// lowers the lifted surface (Lawson 1977; de Berg et al., *Computational Geometry*, 9.1).
    ///
    /// Unlike [`Mesh::legalize`], a flip here may create an edge that does not end at the new
    /// vertex; `on_flip` is told the half-edge of every diagonal a flip makes.
    pub fn legalize_all(&mut self, stack: &mut Vec<u32>, on_flip: impl FnMut(&Self, u32)) -> u32 {
        self.lawson::<true>(stack, on_flip)
    }

    /// The flip loop of both: `OUTER` also checks the two edges that do not face the apex.
    #[inline]
    fn lawson<const OUTER: bool>(
        &mut self,
        stack: &mut Vec<u32>,
        mut on_flip: impl FnMut(&Self, u32),
    ) -> u32 {
        let mut flips = 0;
        while let Some(e) = stack.pop() {
            if self.is_illegal(e) {
                let [p, q] = self.flip(e);
                on_flip(self, p + 1);
                // p = u→w and q = w→v face the apex; next(q) = v→m and prev(p) = m→u don't.
                stack.extend([p, q]);
                if OUTER {
                    stack.extend([super::mesh::next(q), super::mesh::prev(p)]);
                }
                flips += 1;
            }
        }
        flips
    }

    /// Whether the edge of `e` is interior, not constrained, and its far vertex lies strictly
    /// inside the circumcircle of `e`'s triangle.
    #[inline]
    fn is_illegal(&self, e: u32) -> bool {
        let f = self.twin(e);
        f != NONE && !self.is_constrained(e) && {
            let (u, v, m) = (self.point(self.origin(e)), self.point(self.dest(e)), self.point(self.apex(e)));
            is_in_circle(u, v, m, self.point(self.apex(f)))
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::geom::{Mesh, Point, Rect, Vertex};

    #[test]
    fn boundary_split_of_p1p2_flips_the_diagonal_into_the_shorter_p5p4() {
        // The paper's figure: P5 = (0.5, 0) on P1P2; P4 = (0, 1) is inside the circle through
        // P5, P2, P3 ... so P1P3 gives way to P5P4.
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let e = mesh.find_edge(0, 1).unwrap();
        let split = mesh.split(e, Vertex { x: 0.5, y: 0.0, z: 0.0 });
        let mut stack = split.link().to_vec();
        let mut diagonals = Vec::new();
        let flips = mesh.legalize(&mut stack, |mesh, d| diagonals.push((mesh.origin(d), mesh.dest(d))));
        mesh.check_invariants().unwrap();
        assert_eq!(flips, 1);
        assert_eq!(diagonals, [(3, 4)], "the new diagonal runs P4 → P5");
        assert!(mesh.find_edge(0, 2).is_none(), "P1P3 survived");
        assert!(mesh.find_edge(4, 3).is_some(), "P5P4 missing");
        assert!(mesh.is_delaunay());
        assert!(stack.is_empty());
    }

    #[test]
    fn cocircular_quadrilaterals_are_not_flipped() {
        // The centre split of the square leaves four right triangles whose outer quadrilaterals
        // are cocircular with nothing strictly inside: no flip.
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let e = mesh.find_edge(0, 2).unwrap();
        let split = mesh.split(e, Vertex { x: 0.5, y: 0.5, z: 0.0 });
        let mut stack = split.link().to_vec();
        assert_eq!(mesh.legalize(&mut stack, |_, _| {}), 0);
        assert_eq!(mesh.point(4), Point::new(0.5, 0.5));
        assert!(mesh.is_delaunay());
    }
}
