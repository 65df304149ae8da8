//! The queue of candidate edges, worst first: a 4-ary max-heap of the top values over buckets
//! of the rest, with lazy deletion.
//!
//! Written here rather than taken from std or a crate because the order needs context: an
//! entry holds only the criterion value, the two vertex ids and a half-edge hint (20 bytes),
//! and ties are broken by edge length, looked up from the vertices when (rarely, for a smooth
//! F) two values are equal. std's `BinaryHeap` and `dary_heap` need a context-free `Ord`, which
//! would mean storing the length too: 28-byte entries, more memory and cache traffic on the
//! hottest structure of the run.
//!
//! Most entries are never popped: a run ends with three to four queued edges per vertex, all
//! below the last value split. One heap of all of them costs a pop a cache miss per level at
//! 10^6 vertices. So only the entries in the top band of values (1/16 of an octave) are in
//! the heap; the others wait in a bucket per band, appended to in order, and a band is
//! heapified when the heap above it runs dry. The pop order is the heap's order, exactly:
//! every entry in a bucket is below every entry in the heap.

use super::bands::{Buckets, band};
use crate::geom::Vertex;
use std::cmp::Ordering;

/// An edge (a, b), a < b, with its criterion value and where it was when queued.
///
/// Packed to 20 bytes: the hint costs a quarter more queue memory, not half (24 bytes
/// aligned), and the queue is most of a run's memory beyond the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, packed(4))]
pub struct Candidate {
    /// The criterion value (|zₐ − z_b| for variation), finite and ≥ +0.
    pub value: f64,
    /// The smaller vertex id.
    pub a: u32,
    /// The larger vertex id.
    pub b: u32,
    /// A half-edge of (a, b) when it was queued: most edges are still there when popped, and
    /// finding that from one half-edge saves the walk around `a` that proves it
    /// (`Mesh::edge_at`). Not part of the order.
    pub hint: u32,
}

impl Candidate {
    /// A candidate for the edge between `p` and `q` in either order, found at half-edge `hint`.
    #[inline]
    pub fn new(value: f64, p: u32, q: u32, hint: u32) -> Self {
        Self { value, a: p.min(q), b: p.max(q), hint }
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

/// A max-queue of candidates under [`Candidate::cmp`]. Entries are never updated in place: an
/// edge that a flip removes stays until it surfaces, and the caller skips it when the mesh no
/// longer has it. That is cheaper than an indexed heap, because edges are removed far less
/// often than pushed.
#[derive(Debug)]
pub struct WorstEdgeQueue {
    /// Every entry whose band is at least `floor`; empty only when the buckets are too.
    heap: Vec<Candidate>,
    /// The lowest band in the heap.
    floor: usize,
    /// The entries of each band below `floor`.
    buckets: Buckets<Candidate>,
}

const ARITY: usize = 4;

impl WorstEdgeQueue {
    /// An empty queue.
    pub fn new() -> Self {
        Self { heap: Vec::new(), floor: 0, buckets: Buckets::new() }
    }

    /// Adds a candidate; `vertices` must be the ones its ids refer to.
    #[inline]
    pub fn push(&mut self, candidate: Candidate, vertices: &[Vertex]) {
        let band = band(candidate.value);
        if self.heap.is_empty() {
            self.floor = band;
        } else if band < self.floor {
            self.buckets.push(band, candidate);
            return;
        }
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
        let Some(&top) = self.heap.first() else {
            self.refill(vertices);
            return Some(last);
        };
        sift_down(&mut self.heap, 0, last, vertices);
        Some(top)
    }

    /// Moves the highest non-empty band below the floor into the emptied heap.
    #[cold]
    fn refill(&mut self, vertices: &[Vertex]) {
        let Some(band) = self.buckets.highest_below(self.floor) else {
            return;
        };
        self.floor = band;
        self.buckets.drain_into(band, &mut self.heap);
        // Floyd's heap construction: sift every inner node down, the last first.
        let heap = &mut self.heap[..];
        for i in (0..heap.len().div_ceil(ARITY)).rev() {
            sift_down(heap, i, heap[i], vertices);
        }
    }

    /// Whether no entries remain.
    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }
}

impl Default for WorstEdgeQueue {
    fn default() -> Self {
        Self::new()
    }
}

/// Puts `entry` into the hole at `i` of a heap whose subtrees below `i` are heaps: the hole
/// moves down along the worst children while they are worse than `entry`.
#[inline]
fn sift_down(heap: &mut [Candidate], mut i: usize, entry: Candidate, vertices: &[Vertex]) {
    // Children are taken as one subslice per level, so the bounds are checked once.
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
        if entry.cmp(&children[worst], vertices) != Ordering::Less {
            break;
        }
        heap[i] = children[worst];
        i = first + worst;
    }
    heap[i] = entry;
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Values that share a band (1 and 1.03), neighbour bands, zero, and the extremes.
    const VALUES: [f64; 8] = [0.0, 1e-300, 1.0, 1.03, 1.1, 2.0, 3.0, 1e300];

    proptest! {
        /// Pushes and pops interleaved: every pop is the worst of the entries pushed and not yet
        /// popped, by the documented rule written out longhand, whichever band or bucket the
        /// entries went through.
        #[test]
        fn every_pop_is_the_worst_entry_left(
            points in prop::collection::vec((0u8..3, 0u8..3), 6),
            ops in prop::collection::vec(
                prop::option::weighted(0.7, (0..VALUES.len(), 0u32..6, 0u32..6)),
                0..300,
            )
        ) {
            let vertices: Vec<_> = points
                .iter()
                .map(|&(x, y)| Vertex { x: f64::from(x), y: f64::from(y), z: 0.0 })
                .collect();
            let len = |c: &Candidate| {
                let (p, q) = (vertices[c.a as usize], vertices[c.b as usize]);
                (p.x - q.x).powi(2) + (p.y - q.y).powi(2)
            };
            let worse = |x: &Candidate, y: &Candidate| {
                { x.value }.partial_cmp(&{ y.value }).unwrap()
                    .then(len(x).partial_cmp(&len(y)).unwrap())
                    .then((y.a, y.b).cmp(&(x.a, x.b)))
            };
            let mut queue = WorstEdgeQueue::new();
            let mut left: Vec<Candidate> = Vec::new();
            for op in ops.into_iter().chain(std::iter::repeat_n(None, 300)) {
                match op {
                    Some((v, p, q)) => {
                        let c = Candidate::new(VALUES[v], p, q, p + q);
                        queue.push(c, &vertices);
                        left.push(c);
                    }
                    None => {
                        let expected = left.iter().copied().max_by(|x, y| worse(x, y));
                        if let Some(e) = expected {
                            left.remove(left.iter().position(|c| *c == e).unwrap());
                        }
                        prop_assert_eq!(queue.peek().copied(), expected);
                        prop_assert_eq!(queue.pop(&vertices), expected);
                    }
                }
            }
            prop_assert!(queue.is_empty());
        }
    }
}
