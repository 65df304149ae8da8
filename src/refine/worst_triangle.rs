//! The queue of triangles for the error criterion, worst estimate first: a 4-ary max-heap of
//! the top errors over buckets of the rest, indexed by triangle.
//!
//! Every step re-estimates four to six triangles. A lazy heap would push a new entry each time
//! and leave the old one stale, to be popped and skipped later; the heap would hold about
//! twice as many entries as there are triangles. Indexed, a re-estimate moves the triangle's
//! one entry, and a pop is always a live triangle.
//!
//! A re-estimated triangle is mostly a piece of the worst one, its error well below the top.
//! In one heap of every triangle, each such entry sank from near the top to near the bottom, a
//! cache miss per level. So, as in the worst-edge queue, only the top band of errors (1/16 of
//! an octave) is heap-ordered, and the rest wait in a bucket per band, where an entry is put or
//! taken out in one step. At the end of a 10^6-vertex run of Franke's function the heap holds
//! 2% of the entries. The pop order is the heap's order, exactly: every entry in a bucket is
//! below every entry in the heap.

use super::bands::{Buckets, band};
use std::cmp::Ordering;

/// Triangle `t`'s error estimate; `seq` numbers estimates in the order they were made.
#[derive(Debug, Clone, Copy)]
pub struct Entry {
    pub error: f64,
    pub seq: u32,
    pub t: u32,
}

/// Worse first: larger error, then the older estimate. Oldest-first among ties spreads the
/// refinement evenly where F is linear (every error 0) instead of digging at one corner.
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Errors are finite and ≥ +0, where the bit patterns order like the numbers.
        self.error.to_bits().cmp(&other.error.to_bits()).then(other.seq.cmp(&self.seq))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Entry {}

const ARITY: usize = 4;

/// Marks a triangle that has no entry.
const ABSENT: u32 = u32::MAX;

/// Set in a position that is a place in the buckets rather than in the heap.
const IN_BUCKET: u32 = 1 << 31;

/// A max-queue of at most one [`Entry`] per triangle.
#[derive(Debug)]
pub struct WorstTriangleQueue {
    /// Every entry whose band is at least `floor`; empty only when the buckets are too.
    heap: Vec<Entry>,
    /// The lowest band in the heap.
    floor: usize,
    /// The entries of each band below `floor`.
    buckets: Buckets<Entry>,
    /// Where triangle t's entry is: an index in `heap`, [`IN_BUCKET`] with its place in the
    /// buckets, or [`ABSENT`].
    position: Vec<u32>,
}

impl WorstTriangleQueue {
    /// An empty queue with room for `triangles` triangles.
    pub fn with_capacity(triangles: usize) -> Self {
        Self {
            heap: Vec::new(),
            floor: 0,
            buckets: Buckets::with_capacity(triangles),
            position: Vec::with_capacity(triangles),
        }
    }

    /// Gives triangle `entry.t` this entry, in place of the one it had.
    pub fn set(&mut self, entry: Entry) {
        let t = entry.t as usize;
        if self.position.len() <= t {
            self.position.resize(t + 1, ABSENT);
        }
        let new = band(entry.error);
        match self.position[t] {
            ABSENT => {}
            i if i & IN_BUCKET == 0 => {
                let i = i as usize;
                if new >= self.floor {
                    if entry > self.heap[i] {
                        self.sift_up(i, entry)
                    } else {
                        self.sift_down(i, entry)
                    }
                    return;
                }
                self.remove_from_heap(i);
            }
            place => {
                let place = (place & !IN_BUCKET) as usize;
                let old = band(self.buckets.get(place).error);
                if old == new {
                    // Entries of a bucket are unordered: the new one takes the old one's place.
                    self.buckets.replace(place, entry);
                    return;
                }
                if let Some(moved) = self.buckets.swap_remove(old, place) {
                    self.position[moved.t as usize] = place as u32 | IN_BUCKET;
                }
            }
        }
        self.insert(entry, new);
    }

    /// The worst entry.
    #[inline]
    pub fn peek(&self) -> Option<Entry> {
        self.heap.first().copied()
    }

    /// Removes and returns the worst entry.
    pub fn pop(&mut self) -> Option<Entry> {
        let top = *self.heap.first()?;
        self.position[top.t as usize] = ABSENT;
        self.remove_from_heap(0);
        Some(top)
    }

    /// Takes triangle `t`'s entry out of the queue, if it has one.
    pub fn remove(&mut self, t: u32) {
        let Some(&position) = self.position.get(t as usize) else { return };
        self.position[t as usize] = ABSENT;
        match position {
            ABSENT => {}
            i if i & IN_BUCKET == 0 => self.remove_from_heap(i as usize),
            place => {
                let place = (place & !IN_BUCKET) as usize;
                let band = band(self.buckets.get(place).error);
                if let Some(moved) = self.buckets.swap_remove(band, place) {
                    self.position[moved.t as usize] = place as u32 | IN_BUCKET;
                }
            }
        }
    }

    /// Adds an entry for a triangle that has none.
    fn insert(&mut self, entry: Entry, band: usize) {
        if self.heap.is_empty() {
            // Then the buckets are empty too: the entry starts the heap.
            self.floor = band;
        } else if band < self.floor {
            let place = self.buckets.push(band, entry);
            // Below 2^31: at most 2·MAX_VERTICES triangles, plus a part-filled block per band.
            debug_assert!(place < IN_BUCKET as usize);
            self.position[entry.t as usize] = place as u32 | IN_BUCKET;
            return;
        }
        self.heap.push(entry);
        self.sift_up(self.heap.len() - 1, entry);
    }

    /// Takes the entry at `i` out of the heap, whose position the caller updates; refills an
    /// emptied heap from the buckets.
    fn remove_from_heap(&mut self, i: usize) {
        let removed = self.heap[i];
        let last = self.heap.pop().expect("the heap holds the entry");
        if i < self.heap.len() {
            if last > removed { self.sift_up(i, last) } else { self.sift_down(i, last) }
        } else if self.heap.is_empty() {
            self.refill();
        }
    }

    /// Moves the highest non-empty band below the floor into the emptied heap.
    #[cold]
    fn refill(&mut self) {
        let Some(band) = self.buckets.highest_below(self.floor) else {
            return;
        };
        self.floor = band;
        self.buckets.drain_into(band, &mut self.heap);
        for (i, entry) in self.heap.iter().enumerate() {
            self.position[entry.t as usize] = i as u32;
        }
        // Floyd's heap construction: sift every inner node down, the last first.
        for i in (0..self.heap.len().div_ceil(ARITY)).rev() {
            self.sift_down(i, self.heap[i]);
        }
    }

    /// Puts `entry` at `i` or above, moving worse-ranked parents down.
    fn sift_up(&mut self, mut i: usize, entry: Entry) {
        while i > 0 {
            let parent = (i - 1) / ARITY;
            if self.heap[parent] >= entry {
                break;
            }
            self.place(i, self.heap[parent]);
            i = parent;
        }
        self.place(i, entry);
    }

    /// Puts `entry` at `i` or below, moving better-ranked children up.
    fn sift_down(&mut self, mut i: usize, entry: Entry) {
        let len = self.heap.len();
        loop {
            let first = ARITY * i + 1;
            if first >= len {
                break;
            }
            let children = first..(first + ARITY).min(len);
            let best = children.max_by(|&a, &b| self.heap[a].cmp(&self.heap[b])).expect("a child");
            if self.heap[best] <= entry {
                break;
            }
            self.place(i, self.heap[best]);
            i = best;
        }
        self.place(i, entry);
    }

    #[inline]
    fn place(&mut self, i: usize, entry: Entry) {
        self.heap[i] = entry;
        self.position[entry.t as usize] = i as u32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeMap;

    /// Errors that share a band (1 and 1.03), neighbour bands, zero, and the extremes.
    const ERRORS: [f64; 8] = [0.0, 1e-300, 1.0, 1.03, 1.1, 2.0, 3.0, 1e300];

    #[derive(Debug, Clone)]
    enum Op {
        Set { t: u32, error: usize },
        Remove { t: u32 },
        Pop,
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            3 => (0u32..40, 0..ERRORS.len()).prop_map(|(t, error)| Op::Set { t, error }),
            1 => (0u32..45).prop_map(|t| Op::Remove { t }),
            1 => Just(Op::Pop),
        ]
    }

    /// Each triangle's entry as its position finds it, checking on the way that heap entries
    /// are at or above the floor's band and bucket entries below it.
    fn entries(queue: &WorstTriangleQueue) -> BTreeMap<u32, Entry> {
        let mut found = BTreeMap::new();
        for (t, &position) in queue.position.iter().enumerate() {
            let entry = match position {
                ABSENT => continue,
                i if i & IN_BUCKET == 0 => {
                    let entry = queue.heap[i as usize];
                    assert!(band(entry.error) >= queue.floor, "{entry:?} in the heap, floor {}", queue.floor);
                    entry
                }
                place => {
                    let entry = queue.buckets.get((place & !IN_BUCKET) as usize);
                    assert!(band(entry.error) < queue.floor, "{entry:?} in a bucket, floor {}", queue.floor);
                    entry
                }
            };
            assert_eq!(entry.t as usize, t, "triangle {t}'s position holds another's entry");
            found.insert(entry.t, entry);
        }
        found
    }

    proptest! {
        /// Against a map from triangle to entry: every pop is the map's worst entry, each
        /// triangle holds one entry, the last one set (none once removed), and the heap holds
        /// each entry it indexes once, whichever band or bucket the entries went through.
        #[test]
        fn pops_the_worst_live_entry(ops in proptest::collection::vec(op(), 0..400)) {
            let mut queue = WorstTriangleQueue::with_capacity(0);
            let mut model = BTreeMap::new();
            // Drained at the end, so that no entry is left behind in a bucket.
            let drain = std::iter::repeat_n(Op::Pop, 40);
            for (seq, op) in ops.into_iter().chain(drain).enumerate() {
                match op {
                    Op::Set { t, error } => {
                        // Few distinct errors, so ties (broken by age) are common.
                        let entry = Entry { error: ERRORS[error], seq: seq as u32, t };
                        queue.set(entry);
                        model.insert(t, entry);
                    }
                    Op::Remove { t } => {
                        queue.remove(t);
                        model.remove(&t);
                    }
                    Op::Pop => {
                        let expected = model.values().max().copied();
                        prop_assert_eq!(queue.pop().map(|e| (e.t, e.seq)), expected.map(|e| (e.t, e.seq)));
                        if let Some(e) = expected {
                            model.remove(&e.t);
                        }
                    }
                }
                let found = entries(&queue);
                prop_assert_eq!(found.values().map(|e| (e.t, e.seq)).collect::<Vec<_>>(), model.values().map(|e| (e.t, e.seq)).collect::<Vec<_>>());
                let in_heap = queue.position.iter().filter(|&&p| p != ABSENT && p & IN_BUCKET == 0).count();
                prop_assert_eq!(queue.heap.len(), in_heap);
                prop_assert_eq!(queue.heap.is_empty(), model.is_empty());
                prop_assert_eq!(queue.peek().map(|e| e.seq), model.values().max().map(|e| e.seq));
            }
            prop_assert!(model.is_empty());
        }
    }
}
