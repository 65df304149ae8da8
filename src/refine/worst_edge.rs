//! The queue of candidate edges, worst first, with lazy deletion.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// An edge (a, b), a < b, with its criterion value and squared length.
#[derive(Debug, Clone, Copy)]
pub struct Candidate {
    /// The criterion value (|zₐ − z_b| for variation).
    pub value: f64,
    /// Squared length.
    pub len_sq: f64,
    /// The smaller vertex id.
    pub a: u32,
    /// The larger vertex id.
    pub b: u32,
}

impl Candidate {
    /// A candidate for the edge between `p` and `q` in either order.
    #[inline]
    pub fn new(value: f64, len_sq: f64, p: u32, q: u32) -> Self {
        Self { value, len_sq, a: p.min(q), b: p.max(q) }
    }
}

/// Worse first: larger value, then longer, then smaller (a, b). Longer-first matters: with a
/// constant F every value ties, and id order alone would keep splitting the newest, shortest
/// edges around one spot instead of spreading uniformly. Ids make the order total, so the
/// mesh never depends on insertion order inside the heap.
impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.value
            .total_cmp(&other.value)
            .then(self.len_sq.total_cmp(&other.len_sq))
            .then((other.a, other.b).cmp(&(self.a, self.b)))
    }
}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Candidate {}

/// A max-heap of candidates. Entries are never updated in place: an edge that a flip removes
/// stays until it surfaces, and the caller skips it when the mesh no longer has it. That is
/// cheaper than an indexed heap, because edges are removed far less often than pushed.
#[derive(Debug, Default)]
pub struct WorstEdgeQueue {
    heap: BinaryHeap<Candidate>,
}

impl WorstEdgeQueue {
    /// An empty queue with room for `capacity` entries.
    pub fn with_capacity(capacity: usize) -> Self {
        Self { heap: BinaryHeap::with_capacity(capacity) }
    }

    /// Adds a candidate.
    #[inline]
    pub fn push(&mut self, candidate: Candidate) {
        self.heap.push(candidate);
    }

    /// The worst candidate, possibly stale.
    #[inline]
    pub fn peek(&self) -> Option<&Candidate> {
        self.heap.peek()
    }

    /// Removes the worst candidate.
    #[inline]
    pub fn pop(&mut self) -> Option<Candidate> {
        self.heap.pop()
    }

    /// Number of entries, stale ones included.
    pub fn len(&self) -> usize {
        self.heap.len()
    }

    /// Whether no entries remain.
    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn pops_in_the_order_of_a_full_sort(
            entries in prop::collection::vec((0u8..4, 0u8..4, 0u32..6, 0u32..6), 0..60)
        ) {
            let candidates: Vec<_> = entries
                .iter()
                .map(|&(v, l, p, q)| Candidate::new(f64::from(v), f64::from(l), p, q))
                .collect();
            let mut queue = WorstEdgeQueue::with_capacity(candidates.len());
            for &c in &candidates {
                queue.push(c);
            }
            // The oracle: sort by the documented rule, written out longhand.
            let mut sorted = candidates.clone();
            sorted.sort_by(|x, y| {
                y.value.partial_cmp(&x.value).unwrap()
                    .then(y.len_sq.partial_cmp(&x.len_sq).unwrap())
                    .then((x.a, x.b).cmp(&(y.a, y.b)))
            });
            for expected in sorted {
                let got = queue.pop().unwrap();
                prop_assert_eq!((got.value, got.len_sq, got.a, got.b), (expected.value, expected.len_sq, expected.a, expected.b));
            }
            prop_assert!(queue.is_empty());
        }
    }
}
