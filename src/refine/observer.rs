//! What a refinement tells whoever watches it, and asks of them.

use crate::geom::Mesh;
use std::time::Duration;

/// A snapshot for progress reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Vertices so far.
    pub vertices: usize,
    /// Triangles so far.
    pub triangles: usize,
    /// The current worst criterion value (V_n for `variation`).
    pub worst: f64,
    /// Time since the refinement started.
    pub elapsed: Duration,
}

/// How often [`Observer::progress`] is called at most.
pub const PROGRESS_INTERVAL: Duration = Duration::from_millis(50);

/// Watches a refinement. Every method has a no-op default and `refine` is generic over the
/// observer, so an unused hook compiles to nothing in the hot loop.
pub trait Observer {
    /// A progress snapshot of `mesh`, at most every [`PROGRESS_INTERVAL`].
    fn progress(&mut self, _mesh: &Mesh, _progress: &Progress) {}

    /// Checked before every insertion; `true` stops the run with [`StopReason::Cancelled`](super::StopReason::Cancelled).
    /// An observer may also pause the run here (a server giving its worker to another job).
    fn is_cancelled(&self) -> bool {
        false
    }

    /// How long the run has been paused in [`Observer::is_cancelled`], in all so far: time
    /// that counts neither toward the time limit nor in the elapsed time reported, so a
    /// paused run ends as an unpaused one would.
    fn paused(&self) -> Duration {
        Duration::ZERO
    }

    /// The edge (a, b) was chosen to split, before it is split or retired: the worst edge for
    /// `variation`, the edge serving the worst triangle for `error`.
    fn selected(&mut self, _mesh: &Mesh, _a: u32, _b: u32) {}

    /// The edge (a, b) was retired instead of split (for `error`, with its triangle).
    fn retired(&mut self, _a: u32, _b: u32) {}

    /// Vertex `vertex` was inserted and the mesh is consistent again (flips done).
    fn inserted(&mut self, _mesh: &Mesh, _vertex: u32) {}

    /// The run puts its vertices on grid nodes rather than edge midpoints (criterion `error`
    /// on a grid, `semi-recursive`); called before [`Observer::started`].
    fn on_nodes(&mut self) {}

    /// The loop is about to start, after `evaluations` evaluations of F (the corners, and for
    /// `error` the first two triangles' samples).
    fn started(&mut self, _evaluations: u64) {}

    /// The worst criterion value `worst` is about to be compared with the tolerance.
    fn checked(&mut self, _worst: f64) {}

    /// Criterion `error`: triangle `t` now has the estimate e(T) = `error`.
    fn estimated(&mut self, _t: u32, _error: f64) {}

    /// A step that passed the tolerance check ended: half-edge `split` was split (its id
    /// before the split), or with `None` an edge was retired; F has now been evaluated
    /// `evaluations` times in all.
    fn stepped(&mut self, _split: Option<u32>, _evaluations: u64) {}
}

impl Observer for () {}
