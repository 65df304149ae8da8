//! The convergence history a run's stats carry: V_n and the worst criterion value at vertex
//! counts spaced evenly on a log scale, for a log-log plot of the run.
//!
//! A sample is taken at the first tolerance check at or past each mark, so a run and its
//! [`replay`](super::trace::replay) sample the same meshes, and a smaller budget's history is
//! the larger one's cut at its count plus its own final sample.

use super::measures::variation;
use super::params::{Criterion, Method};
use crate::geom::Mesh;

/// The state of a run at one vertex count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Vertices n.
    pub vertices: usize,
    /// V_n = max |zᵢ − zⱼ| over the edges.
    pub variation: f64,
    /// The worst criterion value compared with the tolerance at this count: the largest e(T)
    /// for `error`, the largest |zᵢ − zⱼ| still to split for `variation`. Absent from a final
    /// sample at a count never checked (the budget stopped the run first).
    pub worst: Option<f64>,
}

/// The smallest mark above `n`. The marks are 4·2^k and 6·2^k (4, 6, 8, 12, 16, 24, …): two
/// a doubling, in integers, so every machine samples the same counts.
fn next_mark(n: usize) -> usize {
    let mut mark = 4usize;
    while mark <= n {
        // 4·2^k → 6·2^k → 8·2^k.
        mark = if mark.is_power_of_two() { mark / 2 * 3 } else { mark / 3 * 4 };
    }
    mark
}

/// Samples a run as it checks its worst values.
#[derive(Debug, Clone)]
pub(crate) struct History {
    next: usize,
    samples: Vec<Sample>,
    /// The latest check: the count and the worst value.
    last: Option<(usize, f64)>,
    /// Criterion `variation`: V_n can be known without a walk (see [`History::known`]).
    free: bool,
    /// Method `recursive`: edges, retired ones included, are never removed but by a split.
    recursive: bool,
    /// The largest |zᵢ − zⱼ| of a retired edge, once one was.
    retired_max: Option<f64>,
    /// Criterion `variation`: the count at the stop and the largest |zᵢ − zⱼ| still queued.
    end: Option<(usize, f64)>,
}

impl History {
    pub(crate) fn new(criterion: Criterion, method: Method) -> Self {
        Self {
            next: 4,
            samples: Vec::with_capacity(48),
            last: None,
            free: criterion == Criterion::Variation,
            recursive: method == Method::Recursive,
            retired_max: None,
            end: None,
        }
    }

    /// The edge of the latest check was retired, not split.
    pub(crate) fn retired(&mut self) {
        let value = self.last.map_or(0.0, |(_, worst)| worst);
        self.retired_max = Some(self.retired_max.map_or(value, |m| m.max(value)));
    }

    /// V_n without a walk, where it is known. With `variation` the worst value at a check is
    /// the largest |zᵢ − zⱼ| of the queued edges, and every edge is queued but the retired
    /// ones; a retired edge's value is the worst value of the check that retired it. Retired
    /// edges stay in a recursive mesh; a flip may remove one from a Delaunay mesh, so there
    /// only a run that retired none knows V_n.
    fn known(&self, worst: f64) -> Option<f64> {
        match self.retired_max {
            _ if !self.free => None,
            None => Some(worst),
            Some(retired) if self.recursive => Some(worst.max(retired)),
            Some(_) => None,
        }
    }

    /// The run compares `worst` with the tolerance on `mesh` as it stands. Where V_n is not
    /// [known](History::known), the mesh's edges are walked at each mark: about 3.3 walks of
    /// the final mesh over a run.
    #[inline(always)]
    pub(crate) fn check(&mut self, mesh: &Mesh, worst: f64) {
        let n = mesh.num_vertices();
        self.last = Some((n, worst));
        if n >= self.next {
            self.sample(mesh, worst);
        }
    }

    /// A sample at a mark, out of line: the check in the refinement loop stays a compare.
    #[cold]
    #[inline(never)]
    fn sample(&mut self, mesh: &Mesh, worst: f64) {
        let (n, known) = (mesh.num_vertices(), self.known(worst));
        debug_assert!(known.is_none_or(|v| v.to_bits() == variation(mesh).to_bits()), "V_n is not {known:?}");
        let variation = known.unwrap_or_else(|| variation(mesh));
        self.samples.push(Sample { vertices: n, variation, worst: Some(worst) });
        self.next = next_mark(n);
    }

    /// Criterion `variation` stopped at `n` vertices with `worst` the largest |zᵢ − zⱼ| of the
    /// edges still queued, so [`History::finish`] may know V_n without a walk.
    pub(crate) fn ended(&mut self, n: usize, worst: f64) {
        self.end = Some((n, worst));
    }

    /// V_n of the final mesh: that of the last of [`History::finish`]'s samples.
    pub(crate) fn final_variation(samples: &[Sample]) -> f64 {
        samples.last().map_or(0.0, |s| s.variation)
    }

    /// The samples, ending with the final mesh's (with the worst value of a check at its
    /// count, as when the tolerance stopped the run).
    pub(crate) fn finish(mut self, mesh: &Mesh) -> Vec<Sample> {
        let n = mesh.num_vertices();
        if self.samples.last().is_none_or(|s| s.vertices != n) {
            let at_n = |state: Option<(usize, f64)>| state.filter(|&(at, _)| at == n).map(|(_, w)| w);
            let worst = at_n(self.last);
            let known = at_n(self.end).or(worst).and_then(|w| self.known(w));
            debug_assert!(
                known.is_none_or(|v| v.to_bits() == variation(mesh).to_bits()),
                "V_n is not {known:?}"
            );
            let variation = known.unwrap_or_else(|| variation(mesh));
            self.samples.push(Sample { vertices: n, variation, worst });
        }
        self.samples
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_are_four_and_six_times_powers_of_two() {
        let mut marks = vec![];
        let mut n = 3;
        while n < 100 {
            n = next_mark(n);
            marks.push(n);
        }
        assert_eq!(marks, [4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128]);
        assert_eq!(next_mark(1_000_000), 1_048_576);
        assert_eq!(next_mark(5), 6);
    }
}
