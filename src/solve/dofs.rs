//! The degrees of freedom: which vertices are unknowns, and which share a periodic partner's.

use super::element::Position;
use super::error::SolveError;
use super::problem::Problem;
use crate::geom::Point;
use std::collections::HashMap;

/// Which vertices are unknowns: one per vertex off the Dirichlet sides, except that a vertex
/// on the right (top) side of a periodic pair shares its left (bottom) partner's, with the
/// pair's sign; a corner on two pairs goes through both to the bottom-left one.
pub(super) struct Numbering {
    /// The unknown of each vertex, `None` on a Dirichlet side.
    pub(super) unknown: Vec<Option<usize>>,
    /// u at the vertex = sign · the unknown.
    pub(super) sign: Vec<f64>,
    /// g at the Dirichlet vertices, 0 elsewhere.
    pub(super) u: Vec<f64>,
    /// The vertex that owns each unknown.
    pub(super) masters: Vec<usize>,
}

impl Numbering {
    pub(super) fn new<P: Position>(problem: &Problem<'_>, vertices: &[P]) -> Result<Self, SolveError> {
        let (domain, boundary) = (problem.domain(), problem.boundary());
        let mut numbering = Self {
            unknown: vec![None; vertices.len()],
            sign: vec![1.0; vertices.len()],
            u: vec![0.0; vertices.len()],
            masters: Vec::new(),
        };
        // Each vertex's partner across each periodic pair, found by its exact coordinate.
        let index = |on: &dyn Fn(Point) -> bool, along: fn(Point) -> f64| -> HashMap<u64, usize> {
            let on_side = vertices.iter().enumerate().filter(|(_, p)| on(p.position()));
            on_side.map(|(v, p)| ((along(p.position()) + 0.0).to_bits(), v)).collect()
        };
        let across_x = boundary.across_x().map(|sign| (sign, index(&|p| p.x == domain.x0(), |p| p.y)));
        let across_y = boundary.across_y().map(|sign| (sign, index(&|p| p.y == domain.y0(), |p| p.x)));
        // The vertex whose unknown `v` takes, and the sign.
        let master = |v: usize| -> Result<(usize, f64), SolveError> {
            let (mut v, mut sign) = (v, 1.0);
            let p = vertices[v].position();
            if let Some((s, left)) = &across_x
                && p.x == domain.x1()
            {
                v = *left.get(&(p.y + 0.0).to_bits()).ok_or(SolveError::Unmatched { x: p.x, y: p.y })?;
                sign *= s;
            }
            let q = vertices[v].position();
            if let Some((s, bottom)) = &across_y
                && q.y == domain.y1()
            {
                v = *bottom.get(&(q.x + 0.0).to_bits()).ok_or(SolveError::Unmatched { x: q.x, y: q.y })?;
                sign *= s;
            }
            Ok((v, sign))
        };
        // Partners take their master's unknown once every master has one.
        let mut partners = Vec::new();
        for (v, vertex) in vertices.iter().enumerate() {
            let p = vertex.position();
            if problem.is_dirichlet(p) {
                let g = problem.g_at(p);
                if !g.is_finite() {
                    return Err(SolveError::NonFiniteG { x: p.x, y: p.y, value: g, vertex: v });
                }
                numbering.u[v] = g;
                continue;
            }
            match master(v)? {
                (m, _) if m == v => {
                    numbering.unknown[v] = Some(numbering.masters.len());
                    numbering.masters.push(v);
                }
                (m, sign) => partners.push((v, m, sign)),
            }
        }
        for (v, m, sign) in partners {
            numbering.unknown[v] = numbering.unknown[m];
            numbering.sign[v] = sign;
        }
        Ok(numbering)
    }
}
