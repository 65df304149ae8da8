//! The memory budget: admission control charges what a request will hold before the work
//! starts, so that load is refused with a 503 instead of ending in an out-of-memory kill.
//!
//! Charged: request bodies while they are read, each job from submission to its end (its
//! decoded grid and its vertex budget at the bytes per vertex measured below), and the
//! cache's meshes in memory as they stand.

use crate::refine::Criterion;
use crate::source::Source;
use crate::spec::{JobSpec, Work};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Peak bytes per vertex of a mesh job: the engine, the result and its trace. Measured with
/// `/usr/bin/time -f %M meshfit mesh --function 'sin(9*x)*cos(7*y)' --max-vertices 1000000`:
/// 158 MB with `--criterion variation` (its queue entries carry a half-edge since 3082c02),
/// 212 MB with `error`; with the 24-byte copy of each vertex a running job keeps for viewers,
/// 236 MB; rounded up.
pub const MESH_BYTES_PER_VERTEX: u64 = 256;

/// [`MESH_BYTES_PER_VERTEX`] for criterion `curvature`, whose gradients and lazier queue take
/// more: the command line's 247 MB at 10^6 vertices (2026-12-07, measured as below), with
/// the viewers' copy 271 MB; rounded up.
pub const CURVATURE_BYTES_PER_VERTEX: u64 = 288;

/// Peak bytes per vertex of a solution: the sparse Cholesky factor dominates. Measured the
/// same way on `meshfit solve` (2026-12-06, 08f08c1): at 10^5 vertices a Poisson peak 140 MB and
/// examples/requests/electromagnet.json 169 MB (Newton keeps its analysis and Jacobian), at
/// 2·10^5 the README's magnet 276 MB and the electromagnet 275 MB; rounded up from the
/// electromagnet at 10^5.
pub const SOLUTION_BYTES_PER_VERTEX: u64 = 1792;

/// Peak bytes per vertex of the command line's `meshfit mesh` (no viewer copy, no trace):
/// measured as the server's `MESH_BYTES_PER_VERTEX` is, 163 MB at 10^6 vertices with `--criterion
/// variation`, 201 MB with `error` and 247 MB with `curvature` (2026-12-07), the output written
/// as JSON or PLY; rounded up.
pub const fn cli_mesh_bytes_per_vertex(criterion: Criterion) -> u64 {
    match criterion {
        Criterion::Variation => 176,
        Criterion::Error => 224,
        Criterion::Curvature => 256,
    }
}

/// Bytes per grid point once decoded (f64 samples).
pub const GRID_BYTES_PER_POINT: u64 = 8;

/// The budget, and the bytes charged against it now.
pub struct Budget {
    limit: u64,
    charged: AtomicU64,
    /// Bytes held outside the charges (the cache's meshes), read at each admission.
    held: Box<dyn Fn() -> u64 + Send + Sync>,
}

impl std::fmt::Debug for Budget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Budget").field("limit", &self.limit).field("charged", &self.charged()).finish()
    }
}

/// Bytes that did not fit: what was asked and what was left.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OverBudget {
    /// Bytes the request needed.
    pub needed: u64,
    /// Bytes left in the budget when it asked.
    pub available: u64,
}

/// Bytes charged until dropped; it can grow (a body being read).
#[derive(Debug)]
pub struct Charge {
    budget: Arc<Budget>,
    bytes: u64,
}

impl Budget {
    /// A budget of `limit` bytes, of which `held` reports what is held outside the charges.
    pub fn new(limit: u64, held: impl Fn() -> u64 + Send + Sync + 'static) -> Arc<Self> {
        Arc::new(Self { limit, charged: AtomicU64::new(0), held: Box::new(held) })
    }

    /// The budget in bytes.
    pub fn limit(&self) -> u64 {
        self.limit
    }

    /// Bytes charged now (not counting those held outside the charges).
    pub fn charged(&self) -> u64 {
        self.charged.load(Ordering::SeqCst)
    }

    /// Charges `bytes`, or says why not.
    ///
    /// # Errors
    /// When the charges, the bytes held and `bytes` would pass the limit.
    pub fn charge(self: &Arc<Self>, bytes: u64) -> Result<Charge, OverBudget> {
        let mut charge = Charge { budget: self.clone(), bytes: 0 };
        charge.grow_to(bytes)?;
        Ok(charge)
    }

    fn reserve(&self, bytes: u64) -> Result<(), OverBudget> {
        let held = (self.held)();
        self.charged
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |charged| {
                let total = charged.checked_add(held)?.checked_add(bytes)?;
                (total <= self.limit).then_some(charged + bytes)
            })
            .map(drop)
            .map_err(|charged| OverBudget {
                needed: bytes,
                available: self.limit.saturating_sub(charged.saturating_add(held)),
            })
    }
}

impl Charge {
    /// Bytes charged.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Grows the charge to `bytes` (never shrinks it).
    ///
    /// # Errors
    /// When the growth does not fit; the charge keeps what it had.
    pub fn grow_to(&mut self, bytes: u64) -> Result<(), OverBudget> {
        let more = bytes.saturating_sub(self.bytes);
        if more > 0 {
            self.budget.reserve(more)?;
        }
        self.bytes = self.bytes.max(bytes);
        Ok(())
    }
}

impl Drop for Charge {
    fn drop(&mut self) {
        self.budget.charged.fetch_sub(self.bytes, Ordering::SeqCst);
    }
}

/// A `/proc/meminfo` entry in bytes, e.g. `MemTotal`.
fn meminfo(key: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib = text.lines().find_map(|l| l.strip_prefix(key)?.strip_prefix(':'))?.trim().strip_suffix("kB")?;
    kib.trim().parse::<u64>().ok().map(|k| k * 1024)
}

/// A cgroup v2 file of the process's container as a number (`max` reads as none).
fn cgroup(file: &str) -> Option<u64> {
    std::fs::read_to_string(format!("/sys/fs/cgroup/{file}")).ok()?.trim().parse().ok()
}

/// The default budget: half the machine's memory, or of the container's limit when it has a
/// smaller one (cgroup v2 `memory.max`).
pub fn default_limit() -> u64 {
    match (meminfo("MemTotal"), cgroup("memory.max")) {
        (Some(t), Some(c)) => t.min(c) / 2,
        (Some(m), None) | (None, Some(m)) => m / 2,
        // Not Linux, or no /proc: 2 GiB, a small machine's half.
        (None, None) => 2 << 30,
    }
}

/// Memory a new allocation can have now: the machine's `MemAvailable`, or what is left under
/// the container's limit when that is less; `None` where neither can be read (not Linux).
pub fn available_memory() -> Option<u64> {
    let container = cgroup("memory.max").map(|max| max.saturating_sub(cgroup("memory.current").unwrap_or(0)));
    match (meminfo("MemAvailable"), container) {
        (Some(a), Some(c)) => Some(a.min(c)),
        (a, c) => a.or(c),
    }
}

/// The most memory a job of `spec` holds while it waits and runs: its decoded grid and its
/// vertex budget at the measured bytes per vertex.
pub(crate) fn memory_bytes(spec: &JobSpec) -> u64 {
    match &spec.work {
        Work::Mesh(m) => {
            let grid = match &*m.source {
                Source::Grid(g) => (g.nx() * g.ny()) as u64 * GRID_BYTES_PER_POINT,
                Source::Expression(_) => 0,
            };
            let per_vertex = match m.params.criterion() {
                Criterion::Curvature => CURVATURE_BYTES_PER_VERTEX,
                Criterion::Variation | Criterion::Error => MESH_BYTES_PER_VERTEX,
            };
            grid + m.params.max_vertices() as u64 * per_vertex
        }
        Work::Solve(s) => s.settings.max_vertices as u64 * SOLUTION_BYTES_PER_VERTEX,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU64;

    #[test]
    fn the_machine_has_memory_available_and_less_than_it_has_in_all() {
        // Linux here: both are read from /proc/meminfo.
        let (available, total) = (available_memory().unwrap(), meminfo("MemTotal").unwrap());
        assert!(available > 0 && available <= total, "{available} of {total}");
        assert!(default_limit() <= total / 2);
    }

    #[test]
    fn charges_count_until_dropped_and_held_bytes_count_too() {
        let held = Arc::new(AtomicU64::new(0));
        let outside = held.clone();
        let budget = Budget::new(1000, move || outside.load(Ordering::SeqCst));
        let a = budget.charge(600).unwrap();
        assert_eq!(budget.charge(500).unwrap_err(), OverBudget { needed: 500, available: 400 });
        let mut b = budget.charge(300).unwrap();
        assert_eq!(b.grow_to(500).unwrap_err(), OverBudget { needed: 200, available: 100 });
        assert_eq!((b.bytes(), budget.charged()), (300, 900), "a failed growth keeps what it had");
        drop(a);
        b.grow_to(500).unwrap();
        held.store(600, Ordering::SeqCst);
        assert!(budget.charge(1).is_err(), "the cache's bytes leave no room");
        drop(b);
        assert_eq!(budget.charged(), 0);
        assert!(budget.charge(400).is_ok());
    }

    #[test]
    fn the_default_is_a_fraction_of_a_real_amount_of_memory() {
        let limit = default_limit();
        assert!(limit >= 64 << 20, "{limit}");
    }
}
