//! Independent checks of a mesh: structural invariants and the Delaunay property.
//!
//! Tests run [`Mesh::check_invariants`] after every mutation (spade's `sanity_check`); the
//! refinement runs [`Mesh::is_delaunay`] once at the end, so the reported `delaunay` flag is
//! verified, never assumed.

use super::Point;
use super::mesh::{Mesh, NONE};
use super::predicates::{is_ccw, is_in_circle};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};

/// A broken mesh invariant, described for a human.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InvariantError(pub String);

impl fmt::Display for InvariantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for InvariantError {}

macro_rules! ensure {
    ($cond:expr, $($msg:tt)+) => {
        if !$cond {
            return Err(InvariantError(format!($($msg)+)));
        }
    };
}

impl Mesh {
    /// Checks every structural invariant; `Err` names the first one broken.
    ///
    /// - corners and twins have 3 entries per triangle, every corner is a vertex id;
    /// - twins are symmetric and run in opposite directions;
    /// - a half-edge without twin lies on one side of the rectangle;
    /// - every triangle is strictly counter-clockwise by exact `orient2d`;
    /// - every vertex lies in the closed rectangle, has a finite value, and its outgoing
    ///   half-edge starts at it;
    /// - every constrained edge is an edge of the mesh;
    /// - Euler's relation for a triangulated convex polygon: triangles = 2n − h − 2.
    pub fn check_invariants(&self) -> Result<(), InvariantError> {
        let n = self.vertices.len();
        ensure!(self.half.len().is_multiple_of(3), "{} half-edges is not a multiple of 3", self.half.len());
        ensure!(self.outgoing.len() == n, "outgoing has {} entries for {n} vertices", self.outgoing.len());
        for (e, v) in self.half.iter().map(|h| h.origin).enumerate() {
            ensure!((v as usize) < n, "half-edge {e} starts at unknown vertex {v}");
        }
        for e in 0..self.half.len() as u32 {
            let t = self.twin(e);
            let (a, b) = (self.origin(e), self.dest(e));
            if t == NONE {
                let (p, q) = (self.point(a), self.point(b));
                let r = self.rect;
                let on_side = (p.x == q.x && (p.x == r.x0() || p.x == r.x1()))
                    || (p.y == q.y && (p.y == r.y0() || p.y == r.y1()));
                ensure!(on_side, "boundary half-edge {e} ({a}→{b}) is not on a side of {r}");
            } else {
                ensure!((t as usize) < self.half.len(), "half-edge {e} has twin {t} out of range");
                ensure!(self.twin(t) == e, "twin of {e} is {t}, whose twin is {}", self.twin(t));
                ensure!(
                    self.origin(t) == b && self.dest(t) == a,
                    "half-edge {e} ({a}→{b}) and its twin {t} ({}→{}) do not run opposite",
                    self.origin(t),
                    self.dest(t)
                );
            }
        }
        for t in 0..self.num_triangles() {
            let [p, q, r] = self.triangle(t);
            ensure!(
                is_ccw(self.point(p), self.point(q), self.point(r)),
                "triangle {t} ({p}, {q}, {r}) is not strictly counter-clockwise: {:?} {:?} {:?}",
                self.point(p),
                self.point(q),
                self.point(r)
            );
        }
        let r = self.rect;
        for (v, vertex) in self.vertices.iter().enumerate() {
            ensure!(vertex.z.is_finite(), "vertex {v} has non-finite value {}", vertex.z);
            ensure!(r.contains(vertex.point()), "vertex {v} at ({}, {}) is outside {r}", vertex.x, vertex.y);
            let e = self.outgoing[v];
            ensure!(
                (e as usize) < self.half.len() && self.origin(e) == v as u32,
                "outgoing half-edge {e} of vertex {v} does not start there"
            );
        }
        self.check_constraints()?;
        let h = self.num_boundary_vertices();
        ensure!(
            self.num_triangles() + h + 2 == 2 * n,
            "{} triangles, but 2n − h − 2 = {} for n = {n}, h = {h}",
            self.num_triangles(),
            2 * n - h - 2
        );
        Ok(())
    }

    /// The first interior half-edge, not constrained, whose far vertex lies strictly inside the
    /// circumcircle of its triangle, if any.
    ///
    /// A large mesh is checked in two halves on two threads; the answer is the same edge
    /// either way, the first half's when both have one (the second half then stops early).
    pub fn find_non_delaunay_edge(&self) -> Option<u32> {
        let end = self.half.len() as u32;
        // Small meshes first: asking for the parallelism is a system call.
        if end < PARALLEL_CHECK || std::thread::available_parallelism().map_or(1, usize::from) < 2 {
            return self.find_non_delaunay_in(0..end, &AtomicBool::new(false));
        }
        let middle = end / 2;
        let first_found = AtomicBool::new(false);
        std::thread::scope(|scope| {
            let second = scope.spawn(|| self.find_non_delaunay_in(middle..end, &first_found));
            let first = self.find_non_delaunay_in(0..middle, &AtomicBool::new(false));
            first_found.store(first.is_some(), Ordering::Relaxed);
            let second = second.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            first.or(second)
        })
    }

    /// [`Mesh::find_non_delaunay_edge`] among the half-edges of `range`; gives up (`None`)
    /// once `stop` is set, between batches.
    ///
    /// The check is memory-bound: an edge's four corners are scattered over the vertices. So
    /// a batch of edges gathers its corners' ids, then their points, then runs the predicate,
    /// and the loads of a batch overlap instead of each waiting behind the previous test.
    fn find_non_delaunay_in(&self, range: std::ops::Range<u32>, stop: &AtomicBool) -> Option<u32> {
        let mut edges = [0u32; CHECK_BATCH];
        let mut corners = [[0u32; 4]; CHECK_BATCH];
        let mut quads = [[Point::new(0.0, 0.0); 4]; CHECK_BATCH];
        let mut next = range.start;
        while next < range.end && !stop.load(Ordering::Relaxed) {
            let mut len = 0;
            while len < CHECK_BATCH && next < range.end {
                let f = self.twin(next);
                if f != NONE && next < f && !self.is_constrained(next) {
                    edges[len] = next;
                    len += 1;
                }
                next += 1;
            }
            for (corner, &e) in corners.iter_mut().zip(&edges[..len]) {
                *corner = [self.origin(e), self.dest(e), self.apex(e), self.apex(self.twin(e))];
            }
            for (quad, corner) in quads.iter_mut().zip(&corners[..len]) {
                *quad = corner.map(|v| self.point(v));
            }
            if let Some(k) = quads[..len].iter().position(|&[a, b, c, d]| is_in_circle(a, b, c, d)) {
                return Some(edges[k]);
            }
        }
        None
    }

    /// Whether every interior edge passes the exact in-circle test (a Delaunay triangulation),
    /// constrained edges excepted (then a constrained Delaunay triangulation).
    pub fn is_delaunay(&self) -> bool {
        self.find_non_delaunay_edge().is_none()
    }
}

/// Interior edges per batch of the Delaunay check.
const CHECK_BATCH: usize = 64;

/// Half-edges from which the Delaunay check takes a second thread (about 40,000 vertices,
/// where the check takes milliseconds and a thread tens of microseconds).
const PARALLEL_CHECK: u32 = 1 << 18;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{Rect, Vertex};

    #[test]
    fn check_invariants_catches_a_corrupted_twin_and_a_clockwise_triangle() {
        let mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        let mut broken = mesh.clone();
        broken.half[2].twin = 4;
        assert!(broken.check_invariants().unwrap_err().0.contains("twin"));
        let mut clockwise = mesh.clone();
        clockwise.half.swap(0, 1);
        assert!(clockwise.check_invariants().is_err());
        let mut nan = mesh;
        nan.vertices[3] = Vertex { x: 0.0, y: 1.0, z: f64::NAN };
        assert!(nan.check_invariants().unwrap_err().0.contains("non-finite"));
    }

    /// The check on two threads answers what one scan of every half-edge answers: nothing on a
    /// Delaunay mesh, the edge made illegal in the second half, and the first of the many on a
    /// recursive mesh.
    #[test]
    fn the_two_threads_find_the_edge_one_scan_finds() {
        use crate::refine::{Criterion, Method, Params, refine};
        let f = |x: f64, y: f64| (5.0 * x).sin() * y;
        let params = Params::new(50_000).unwrap();
        let scan =
            |mesh: &Mesh| mesh.find_non_delaunay_in(0..mesh.num_halfedges() as u32, &AtomicBool::new(false));
        let mut mesh = refine(&f, Rect::unit(), &params, &mut ()).unwrap().mesh;
        let end = mesh.num_halfedges() as u32;
        assert!(end >= PARALLEL_CHECK, "{end} half-edges take one thread");
        assert_eq!(mesh.find_non_delaunay_edge(), None);

        // A convex quadrilateral in the second half whose far corner is strictly outside the
        // circle: its flipped diagonal is strictly illegal.
        let e = (end / 2..end)
            .find(|&e| {
                let t = mesh.twin(e);
                t != NONE && t > end / 2 && {
                    let [u, v, m, w] =
                        [mesh.origin(e), mesh.dest(e), mesh.apex(e), mesh.apex(t)].map(|v| mesh.point(v));
                    is_ccw(u, w, m) && is_ccw(w, v, m) && is_in_circle(u, w, m, v)
                }
            })
            .expect("a flippable edge");
        mesh.flip(e);
        let found = mesh.find_non_delaunay_edge();
        assert!(found.is_some_and(|k| k >= end / 2), "found {found:?}");
        assert_eq!(found, scan(&mesh));

        let recursive = refine(
            &f,
            Rect::unit(),
            &Params::builder(50_000)
                .method(Method::Recursive)
                .criterion(Criterion::Variation)
                .build()
                .unwrap(),
            &mut (),
        )
        .unwrap()
        .mesh;
        let found = recursive.find_non_delaunay_edge();
        assert!(found.is_some());
        assert_eq!(found, scan(&recursive));
    }

    #[test]
    fn a_skinny_diagonal_in_a_rectangle_is_still_delaunay_but_a_bad_one_is_not() {
        let mut mesh = Mesh::new(Rect::unit(), [0.0; 4]);
        assert!(mesh.is_delaunay(), "the square's corners are cocircular");
        // Move P4 inwards: P1P3 is then not Delaunay (P4 inside the circle of P1P2P3).
        mesh.vertices[3] = Vertex { x: 0.1, y: 0.9, z: 0.0 };
        assert!(!mesh.is_delaunay());
    }
}
