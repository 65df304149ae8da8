//! The queue of triangles for the error criterion, worst estimate first: a 4-ary max-heap
//! indexed by triangle.
//!
//! Every step re-estimates four to six triangles. A lazy heap would push a new entry each time
//! and leave the old one stale, to be popped and skipped later; the heap would hold about
//! twice as many entries as there are triangles. Indexed, a re-estimate moves the triangle's
//! one entry up or down in place, and a pop is always a live triangle.

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

/// A max-heap of at most one [`Entry`] per triangle.
#[derive(Debug, Default)]
pub struct WorstTriangleQueue {
    heap: Vec<Entry>,
    /// Where triangle t's entry is in `heap`, or [`ABSENT`].
    position: Vec<u32>,
}

impl WorstTriangleQueue {
    /// An empty queue with room for `triangles` triangles.
    pub fn with_capacity(triangles: usize) -> Self {
        Self { heap: Vec::with_capacity(triangles), position: Vec::with_capacity(triangles) }
    }

    /// Gives triangle `entry.t` this entry, in place of the one it had.
    pub fn set(&mut self, entry: Entry) {
        let t = entry.t as usize;
        if self.position.len() <= t {
            self.position.resize(t + 1, ABSENT);
        }
        match self.position[t] {
            ABSENT => {
                self.heap.push(entry);
                self.sift_up(self.heap.len() - 1, entry);
            }
            i => {
                let i = i as usize;
                if entry > self.heap[i] { self.sift_up(i, entry) } else { self.sift_down(i, entry) }
            }
        }
    }

    /// The worst entry.
    #[inline]
    pub fn peek(&self) -> Option<Entry> {
        self.heap.first().copied()
    }

    /// Removes and returns the worst entry.
    pub fn pop(&mut self) -> Option<Entry> {
        let top = *self.heap.first()?;
        let last = self.heap.pop().expect("the heap has a first entry");
        self.position[top.t as usize] = ABSENT;
        if !self.heap.is_empty() {
            self.sift_down(0, last);
        }
        Some(top)
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

    #[derive(Debug, Clone)]
    enum Op {
        Set { t: u32, error: u8 },
        Pop,
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            3 => (0u32..40, any::<u8>()).prop_map(|(t, error)| Op::Set { t, error }),
            1 => Just(Op::Pop),
        ]
    }

    proptest! {
        /// Against a map from triangle to entry: every pop is the map's worst entry, and each
        /// triangle holds one entry, the last one set.
        #[test]
        fn pops_the_worst_live_entry(ops in proptest::collection::vec(op(), 0..400)) {
            let mut queue = WorstTriangleQueue::default();
            let mut model = BTreeMap::new();
            for (seq, op) in ops.into_iter().enumerate() {
                match op {
                    Op::Set { t, error } => {
                        // Few distinct errors, so ties (broken by age) are common.
                        let entry = Entry { error: f64::from(error % 8), seq: seq as u32, t };
                        queue.set(entry);
                        model.insert(t, entry);
                    }
                    Op::Pop => {
                        let expected = model.values().max().copied();
                        prop_assert_eq!(queue.pop().map(|e| (e.t, e.seq)), expected.map(|e| (e.t, e.seq)));
                        if let Some(e) = expected {
                            model.remove(&e.t);
                        }
                    }
                }
                prop_assert_eq!(queue.heap.len(), model.len());
                prop_assert_eq!(queue.peek().map(|e| e.seq), model.values().max().map(|e| e.seq));
            }
        }
    }
}
