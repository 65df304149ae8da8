//! The queue of candidate edges, worst first: a 4-ary max-heap with lazy deletion.
//!
//! Written here rather than taken from std or a crate because the order needs context: an
//! entry holds only the criterion value and the two vertex ids (16 bytes, four to a cache
//! line), and ties are broken by edge length, looked up from the vertices when (rarely, for a
//! smooth F) two values are equal. std's `BinaryHeap` and `dary_heap` need a context-free
//! `Ord`, which would mean storing the length too: 24-byte entries, a third more memory and
//! cache traffic on the hottest structure of the run. Four children per node halve the depth
//! of a binary heap, and a pop's cost is one cache miss per level.

use crate::geom::Vertex;
use std::cmp::Ordering;

/// An edge (a, b), a < b, with its criterion value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The criterion value (|zₐ − z_b| for variation), finite and ≥ +0.
    pub value: f64,
    /// The smaller vertex id.
    pub a: u32,
    /// The larger vertex id.
    pub b: u32,
}

impl Candidate {
    /// A candidate for the edge between `p` and `q` in either order.
    #[inline]
    pub fn new(value: f64, p: u32, q: u32) -> Self {
        Self { value, a: p.min(q), b: p.max(q) }
    }

    /// Squared length of the edge.
    #[inline]
    pub fn len_sq(&self, vertices: &[Vertex]) -> f64 {
        let (p, q) = (vertices[self.a as usize], vertices[self.b as usize]);
        p.point().distance_sq(q.point())
    }

    /// The queue's order, worse first: larger value, then longer, then smaller (a, b).
    ///
    /// Longer-first matters: with a constant F every value ties, and id order alone would keep
    /// splitting the newest, shortest edges around one spot instead of spreading uniformly.
    /// Ids make the order total, so the mesh never depends on the heap's internal layout.
    #[inline(always)]
    pub fn cmp(&self, other: &Self, vertices: &[Vertex]) -> Ordering {
        // Values are finite and ≥ +0 (an `abs`), where the bit patterns order like the numbers.
        let (x, y) = (self.value.to_bits(), other.value.to_bits());
        if x != y { x.cmp(&y) } else { self.cmp_tied(other, vertices) }
    }

    /// The tie-break, out of line so the common path stays small.
    #[inline(never)]
    fn cmp_tied(&self, other: &Self, vertices: &[Vertex]) -> Ordering {
        self.len_sq(vertices)
            .total_cmp(&other.len_sq(vertices))
            .then((other.a, other.b).cmp(&(self.a, self.b)))
    }
}

/// A max-heap of candidates under [`Candidate::cmp`]. Entries are never updated in place: an
/// edge that a flip removes stays until it surfaces, and the caller skips it when the mesh no
/// longer has it. That is cheaper than an indexed heap, because edges are removed far less
/// often than pushed.
#[derive(Debug, Default)]
pub struct WorstEdgeQueue {
    heap: Vec<Candidate>,
}

const ARITY: usize = 4;

impl WorstEdgeQueue {
    /// An empty queue with room for `capacity` entries.
    pub fn with_capacity(capacity: usize) -> Self {
        Self { heap: Vec::with_capacity(capacity) }
    }

    /// Adds a candidate; `vertices` must be the ones its ids refer to.
    #[inline]
    pub fn push(&mut self, candidate: Candidate, vertices: &[Vertex]) {
        let heap = &mut self.heap;
        let mut i = heap.len();
        heap.push(candidate);
        while i > 0 {
            let parent = (i - 1) / ARITY;
            if candidate.cmp(&heap[parent], vertices) != Ordering::Greater {
                break;
            }
            heap[i] = heap[parent];
            i = parent;
        }
        heap[i] = candidate;
    }

    /// The worst candidate, possibly stale.
    #[inline]
    pub fn peek(&self) -> Option<&Candidate> {
        self.heap.first()
    }

    /// Removes the worst candidate.
    #[inline]
    pub fn pop(&mut self, vertices: &[Vertex]) -> Option<Candidate> {
        let last = self.heap.pop()?;
        let heap = &mut self.heap[..];
        let Some(&top) = heap.first() else {
            return Some(last);
        };
        // Move the hole from the root down along the worst children, then put `last` in it.
        // Children are taken as one subslice per level, so the bounds are checked once.
        let mut i = 0;
        loop {
            let first = ARITY * i + 1;
            if first >= heap.len() {
                break;
            }
            let children = &heap[first..(first + ARITY).min(heap.len())];
            let mut worst = 0;
            for (k, child) in children.iter().enumerate().skip(1) {
                if child.cmp(&children[worst], vertices) == Ordering::Greater {
                    worst = k;
                }
            }
            if last.cmp(&children[worst], vertices) != Ordering::Less {
                break;
            }
            heap[i] = children[worst];
            i = first + worst;
        }
        heap[i] = last;
        Some(top)
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
            points in prop::collection::vec((0u8..3, 0u8..3), 6),
            entries in prop::collection::vec((0u8..4, 0u32..6, 0u32..6), 0..200)
        ) {
            let vertices: Vec<_> = points
                .iter()
                .map(|&(x, y)| Vertex { x: f64::from(x), y: f64::from(y), z: 0.0 })
                .collect();
            let candidates: Vec<_> =
                entries.iter().map(|&(v, p, q)| Candidate::new(f64::from(v), p, q)).collect();
            let mut queue = WorstEdgeQueue::with_capacity(0);
            for &c in &candidates {
                queue.push(c, &vertices);
            }
            // The oracle: a sort by the documented rule, written out longhand.
            let len = |c: &Candidate| {
                let (p, q) = (vertices[c.a as usize], vertices[c.b as usize]);
                (p.x - q.x).powi(2) + (p.y - q.y).powi(2)
            };
            let mut sorted = candidates.clone();
            sorted.sort_by(|x, y| {
                y.value.partial_cmp(&x.value).unwrap()
                    .then(len(y).partial_cmp(&len(x)).unwrap())
                    .then((x.a, x.b).cmp(&(y.a, y.b)))
            });
            for expected in sorted {
                prop_assert_eq!(queue.pop(&vertices), Some(expected));
            }
            prop_assert!(queue.is_empty());
        }
    }
}
