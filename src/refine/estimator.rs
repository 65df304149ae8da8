//! Where a loop gets its values and how criterion `error` ranks triangles: the two traits
//! the engine's loops are generic over, so a mesh of F and a solution's mesh share them.

use crate::geom::{Mesh, NONE, Point, Vertex};

/// Where a refinement gets the value of each new vertex: F at the midpoint for a mesh, the
/// interpolated value between the solves of a boundary value problem.
pub(crate) trait Field {
    /// Why a value could not be had.
    type Error;

    /// z of the midpoint `m` of the edge from `a` to `b`.
    fn midpoint(&mut self, a: Vertex, b: Vertex, m: Point) -> Result<f64, Self::Error>;

    /// [`Field::midpoint`] where the criterion predicts z there as `predicted`: a replay of
    /// a job the client evaluates stands the prediction in for a value not told yet.
    fn predicted_midpoint(
        &mut self,
        a: Vertex,
        b: Vertex,
        m: Point,
        predicted: f64,
    ) -> Result<f64, Self::Error> {
        let _ = predicted;
        self.midpoint(a, b, m)
    }

    /// Evaluations of F so far, for the observer.
    fn evaluations(&self) -> u64 {
        0
    }
}

/// How criterion `error` ranks triangles: F's sampled error for a mesh, a residual indicator
/// for a boundary value problem.
pub(crate) trait Estimator: Field {
    /// Whether `semi-recursive` too bisects the end of the worst triangle's longest-edge path
    /// (then flips), instead of the worst of its long edges.
    const LONGEST_EDGE_PATH: bool = false;

    /// The estimate of triangle `t` and its part on each edge (by half-edge position);
    /// `known` holds an edge's part where a fresh neighbour already measured it.
    fn estimate(
        &mut self,
        mesh: &Mesh,
        t: u32,
        known: [Option<f64>; 3],
    ) -> Result<(f64, [f64; 3]), Self::Error>;

    /// Whether [`Estimator::estimate_many`] beats estimating a step's triangles one by one.
    fn batches(&self) -> bool {
        false
    }

    /// [`Estimator::estimate`] for each triangle of `ts` (sorted), in order, into `out`.
    /// `known[i]` is what fresh triangles outside `ts` know of `ts[i]`'s edges; an edge two
    /// triangles of `ts` share is measured by the first and lent to the second. Estimators that
    /// share work across triangles (one batch of samples) override it, with the same results.
    fn estimate_many(
        &mut self,
        mesh: &Mesh,
        ts: &[u32],
        known: &[[Option<f64>; 3]],
        out: &mut Vec<(f64, [f64; 3])>,
    ) -> Result<(), Self::Error> {
        for (i, &t) in ts.iter().enumerate() {
            let estimate = self.estimate(mesh, t, lend(mesh, ts, i, known[i], out))?;
            out.push(estimate);
        }
        Ok(())
    }

    /// A step rewrote the triangles `touched`; called before any of them is estimated again.
    fn rewritten(&mut self, _mesh: &Mesh, _touched: &[u32]) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// The earlier triangle of `ts` (sorted) on the other side of edge `k` of `ts[i]`: its index
/// in `ts` and the edge's position in it.
pub(super) fn lender(mesh: &Mesh, ts: &[u32], i: usize, k: usize) -> Option<(usize, usize)> {
    let f = mesh.twin(3 * ts[i] + k as u32);
    if f == NONE {
        return None;
    }
    ts[..i].binary_search(&(f / 3)).ok().map(|j| (j, (f % 3) as usize))
}

/// `known` for `ts[i]`, with the edges earlier triangles of `ts` measured (their estimates in
/// `out`) lent to it.
pub(super) fn lend(
    mesh: &Mesh,
    ts: &[u32],
    i: usize,
    mut known: [Option<f64>; 3],
    out: &[(f64, [f64; 3])],
) -> [Option<f64>; 3] {
    for (k, known) in known.iter_mut().enumerate() {
        if known.is_none() {
            *known = lender(mesh, ts, i, k).map(|(j, p)| out[j].1[p]);
        }
    }
    known
}
