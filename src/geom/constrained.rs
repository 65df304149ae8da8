//! Constrained edges: the sides of a boundary value problem's regions, which the mesh follows.
//!
//! The first mesh is spade's constrained Delaunay triangulation of the rectangle's corners
//! and every side; after that the mesh's own operations keep each side made of edges: a split
//! of a constrained edge leaves two constrained halves, and Lawson's flips never take one
//! (a semi-recursive mesh is then *constrained* Delaunay: every edge but the constrained ones
//! passes the in-circle test). Meshes of functions and grids have no constraints and pay one
//! emptiness test per flip candidate.

use super::constraints::Constraints;
use super::mesh::{HalfEdge, Mesh, NONE};
use super::{InvariantError, Point, Rect, Vertex};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// Why a constrained triangulation could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConstrainedError {
    /// A side's end lies outside the rectangle, or is not a finite point spade accepts.
    #[error("the point ({x}, {y}) is outside the rectangle or not a usable coordinate")]
    BadPoint {
        /// Abscissa.
        x: f64,
        /// Ordinate.
        y: f64,
    },
    /// The sides and their crossings alone need more vertices than the budget.
    #[error("the regions' sides and their crossings need more than {budget} vertices, the vertex budget")]
    Budget {
        /// The vertex budget.
        budget: usize,
    },
    /// The triangulation spade made does not make a valid mesh (a bug, or sides so close
    /// together that their crossings round onto one another).
    #[error("the regions' sides do not make a valid triangulation: {0}")]
    Invalid(String),
}

impl Mesh {
    /// The constrained Delaunay triangulation of `rect` with every segment of `sides` made of
    /// its edges; where sides cross, spade inserts the crossing (rounded to f64). Vertices 0..3
    /// are the rectangle's corners, as in [`Mesh::new`]; every vertex's z is 0. At most
    /// `budget` vertices, and room for that many.
    ///
    /// # Errors
    /// [`ConstrainedError`] for a point outside the rectangle, sides that need more than
    /// `budget` vertices (checked side by side, so a tangle of crossings stops early), or a
    /// triangulation that fails [`Mesh::check_invariants`].
    pub fn constrained(rect: Rect, sides: &[[Point; 2]], budget: usize) -> Result<Self, ConstrainedError> {
        let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
        let mut insert = |p: Point| {
            if !rect.contains(p) {
                return Err(ConstrainedError::BadPoint { x: p.x, y: p.y });
            }
            cdt.insert(Point2::new(p.x, p.y)).map_err(|_| ConstrainedError::BadPoint { x: p.x, y: p.y })
        };
        for corner in rect.corners() {
            insert(corner)?;
        }
        let mut ends = Vec::with_capacity(sides.len());
        for &[a, b] in sides {
            ends.push((insert(a)?, insert(b)?));
        }
        for (a, b) in ends {
            if cdt.num_vertices() > budget {
                return Err(ConstrainedError::Budget { budget });
            }
            if a != b {
                cdt.add_constraint_and_split(a, b, |p| p);
            }
        }
        if cdt.num_vertices() > budget {
            return Err(ConstrainedError::Budget { budget });
        }
        let vertices: Vec<Vertex> =
            cdt.vertices().map(|v| Vertex { x: v.position().x, y: v.position().y, z: 0.0 }).collect();
        if vertices[..4].iter().map(|v| v.point()).ne(rect.corners()) {
            return Err(ConstrainedError::Invalid("spade renumbered the corners".into()));
        }
        let triangles: Vec<[u32; 3]> =
            cdt.inner_faces().map(|f| f.vertices().map(|v| v.fix().index() as u32)).collect();
        let constraints: Vec<[u32; 2]> = (cdt.undirected_edges())
            .filter(|e| e.is_constraint_edge())
            .map(|e| e.vertices().map(|v| v.fix().index() as u32))
            .collect();
        Self::from_triangles(rect, vertices, &triangles, &constraints, budget)
            .map_err(|e| ConstrainedError::Invalid(e.to_string()))
    }

    /// A mesh of `rect` from counter-clockwise `triangles` over `vertices`, with `constraints`
    /// (vertex pairs) as constrained edges; those on the rectangle's sides are left out, as
    /// every boundary edge already stays. Checked by [`Mesh::check_invariants`].
    pub(crate) fn from_triangles(
        rect: Rect,
        vertices: Vec<Vertex>,
        triangles: &[[u32; 3]],
        constraints: &[[u32; 2]],
        capacity: usize,
    ) -> Result<Self, InvariantError> {
        let room = capacity.max(vertices.len());
        let mut mesh = Self {
            rect,
            vertices: Vec::with_capacity(room),
            half: Vec::with_capacity(6 * room),
            outgoing: vec![NONE; vertices.len()],
            constraints: Constraints::default(),
        };
        mesh.outgoing.reserve(room - vertices.len());
        mesh.vertices.extend(vertices);
        let mut directed = std::collections::HashMap::with_capacity(3 * triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let e = (3 * t + k) as u32;
                mesh.half.push(HalfEdge { origin: tri[k], twin: NONE });
                directed.insert((tri[k], tri[(k + 1) % 3]), e);
            }
        }
        for e in 0..mesh.half.len() as u32 {
            let (a, b) = (mesh.origin(e), mesh.dest(e));
            if let Some(&f) = directed.get(&(b, a)) {
                mesh.half[e as usize].twin = f;
            }
            let a = a as usize;
            if a < mesh.outgoing.len() && mesh.outgoing[a] == NONE {
                mesh.outgoing[a] = e;
            }
        }
        for &[a, b] in constraints {
            let e = directed.get(&(a, b)).or_else(|| directed.get(&(b, a)));
            let interior = e.is_some_and(|&e| mesh.twin(e) != NONE);
            if interior {
                mesh.constraints.insert(a, b);
            } else if e.is_none() {
                return Err(InvariantError(format!("constraint {a}–{b} is not an edge")));
            }
        }
        mesh.check_invariants()?;
        Ok(mesh)
    }

    /// Whether the edge of half-edge `e` is a constrained edge (a region's side inside the
    /// rectangle).
    #[inline]
    pub fn is_constrained(&self, e: u32) -> bool {
        self.constraints.holds(self.origin(e), self.dest(e))
    }

    /// The number of constrained edges.
    pub fn num_constrained(&self) -> usize {
        self.constraints.len()
    }

    /// Checks that every constrained edge is an edge of the mesh.
    pub(super) fn check_constraints(&self) -> Result<(), InvariantError> {
        for (a, b) in self.constraints.iter() {
            if (a as usize) >= self.vertices.len() || self.find_edge(a, b).is_none() {
                return Err(InvariantError(format!("constrained edge {a}–{b} is not in the mesh")));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::predicates::{Orientation, orientation};
    use proptest::prelude::*;

    fn square(x0: f64, x1: f64, y0: f64, y1: f64) -> Vec<[Point; 2]> {
        let p = [Point::new(x0, y0), Point::new(x1, y0), Point::new(x1, y1), Point::new(x0, y1)];
        (0..4).map(|i| [p[i], p[(i + 1) % 4]]).collect()
    }

    #[test]
    fn a_rectangle_region_is_made_of_constrained_edges_that_survive_splits_and_flips() {
        let mut mesh = Mesh::constrained(Rect::unit(), &square(0.25, 0.61, 0.3, 0.7), 64).unwrap();
        assert_eq!(mesh.num_vertices(), 8);
        assert_eq!(mesh.num_constrained(), 4);
        assert!(mesh.is_delaunay(), "a CDT passes the constrained check");
        // Split constrained edges at their midpoints until each is at most 0.05 long (each side
        // into 8), flipping as refinement does.
        let mut stack = Vec::new();
        while let Some(e) = (0..mesh.num_halfedges() as u32)
            .find(|&e| mesh.is_constrained(e) && mesh.len_sq(e) > 0.051 * 0.051)
        {
            let (a, b) = (mesh.point(mesh.origin(e)), mesh.point(mesh.dest(e)));
            let m = a.midpoint(b);
            let split = mesh.split(e, Vertex { x: m.x, y: m.y, z: 0.0 });
            stack.extend(split.suspects());
            mesh.legalize_all(&mut stack, |_, _| {});
            mesh.check_invariants().unwrap();
        }
        assert_eq!(mesh.num_constrained(), 32);
        assert!(mesh.is_delaunay());
        // Every constrained edge lies on the rectangle's outline.
        for e in (0..mesh.num_halfedges() as u32).filter(|&e| mesh.is_constrained(e)) {
            for p in [mesh.point(mesh.origin(e)), mesh.point(mesh.dest(e))] {
                let on = (p.x == 0.25 || p.x == 0.61) && (0.3..=0.7).contains(&p.y)
                    || (p.y == 0.3 || p.y == 0.7) && (0.25..=0.61).contains(&p.x);
                assert!(on, "{p:?} is off the outline");
            }
        }
    }

    #[test]
    fn crossing_sides_are_split_where_they_cross() {
        let mut sides = square(0.1, 0.5, 0.1, 0.5);
        sides.extend(square(0.3, 0.7, 0.3, 0.7));
        let mesh = Mesh::constrained(Rect::unit(), &sides, 100).unwrap();
        // 4 corners, 8 region corners, 2 crossings.
        assert_eq!(mesh.num_vertices(), 14);
        assert!(mesh.find_edge(0, 1).is_some());
        assert_eq!(mesh.num_constrained(), 12);
    }

    #[test]
    fn sides_that_need_more_vertices_than_the_budget_are_refused() {
        let mut sides = square(0.1, 0.5, 0.1, 0.5);
        sides.extend(square(0.3, 0.7, 0.3, 0.7));
        // 14 vertices with the crossings: 13 is one short, whether the crossings or the
        // corners tip it.
        assert_eq!(
            Mesh::constrained(Rect::unit(), &sides, 13).unwrap_err(),
            ConstrainedError::Budget { budget: 13 }
        );
        assert_eq!(
            Mesh::constrained(Rect::unit(), &sides, 11).unwrap_err(),
            ConstrainedError::Budget { budget: 11 }
        );
        assert_eq!(Mesh::constrained(Rect::unit(), &sides, 14).unwrap().num_vertices(), 14);
    }

    #[test]
    fn a_point_outside_the_rectangle_is_refused() {
        let sides = [[Point::new(0.5, 0.5), Point::new(1.5, 0.5)]];
        let err = Mesh::constrained(Rect::unit(), &sides, 100).unwrap_err();
        assert_eq!(err, ConstrainedError::BadPoint { x: 1.5, y: 0.5 });
    }

    proptest! {
        #[test]
        fn every_side_of_a_random_polygon_is_a_chain_of_constrained_edges(
            centre in (0.3f64..0.7, 0.3f64..0.7),
            radii in proptest::collection::vec(0.05f64..0.25, 3..9),
            turn in 0.0f64..1.0,
        ) {
            // A star-shaped polygon around `centre`: simple by construction.
            let n = radii.len();
            let points: Vec<Point> = (0..n).map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + turn) / n as f64;
                Point::new(centre.0 + radii[i] * a.cos(), centre.1 + radii[i] * a.sin())
            }).collect();
            let sides: Vec<[Point; 2]> = (0..n).map(|i| [points[i], points[(i + 1) % n]]).collect();
            let mesh = Mesh::constrained(Rect::unit(), &sides, 100).unwrap();
            prop_assert_eq!(mesh.num_vertices(), 4 + n);
            prop_assert_eq!(mesh.num_constrained(), n);
            prop_assert!(mesh.is_delaunay());
            for [a, b] in sides {
                let ids = [a, b].map(|p| (0..mesh.num_vertices() as u32).find(|&v| mesh.point(v) == p).unwrap());
                let e = mesh.find_edge(ids[0], ids[1]).unwrap();
                prop_assert!(mesh.is_constrained(e));
                prop_assert_ne!(orientation(a, b, mesh.point(mesh.apex(e))), Orientation::Collinear);
            }
        }
    }
}
