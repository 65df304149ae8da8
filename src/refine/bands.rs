//! Bands of criterion values and the buckets both queues keep below their heaps.
//!
//! Both queues hold many more entries than ever reach the top, most of them far below it. So
//! each heap-orders only the entries at or above a floor band and parks the rest in a bucket
//! per band, unordered; when the heap runs dry, the highest bucket is poured into it.

/// Mantissa bits in a band's key: bands are 1/16 of an octave wide.
const BAND_BITS: u32 = 4;

/// Bands of finite values ≥ +0: the exponent and the top mantissa bits.
const BANDS: usize = 1 << (11 + BAND_BITS);

/// The band of a finite value ≥ +0. Bit patterns of such values order like the values, so
/// bands do too, and equal values share one.
#[inline]
pub(super) fn band(value: f64) -> usize {
    (value.to_bits() >> (52 - BAND_BITS)) as usize
}

/// Entries per block of a bucket (4 KiB of 16-byte entries, a page); 4 in tests, so that their
/// few entries per band chain blocks and reuse freed ones.
const BLOCK: usize = if cfg!(test) { 4 } else { 256 };

/// The bands below a heap's floor: each a chain of fixed-size blocks from one shared pool, so a
/// run's buckets hold their entries and at most one part-filled block each, not the slack of
/// a growing vector per band. A drained band's blocks go back to the pool for the next.
///
/// An entry stays at the place [`Buckets::push`] gave it until [`Buckets::swap_remove`] moves
/// the band's last entry there, so an indexed queue can track where each entry is.
#[derive(Debug)]
pub(super) struct Buckets<T> {
    /// The blocks, `BLOCK` entries each.
    pool: Vec<T>,
    /// What each block of the pool holds.
    blocks: Vec<Block>,
    /// Blocks no band uses.
    free: Vec<u32>,
    /// Each band's last block + 1, or 0 for an empty band. Zero is what a fresh allocation
    /// holds, so the pages of bands a run never uses are never touched.
    last: Vec<u32>,
}

/// A block of a band's chain.
#[derive(Debug, Clone, Copy)]
struct Block {
    /// The band's block before this one + 1, or 0 for its first.
    prev: u32,
    /// How many of its entries are in use.
    fill: u32,
}

impl<T: Copy> Buckets<T> {
    /// No entries.
    pub(super) fn new() -> Self {
        Self::with_capacity(0)
    }

    /// No entries, with room reserved for `capacity` of them.
    pub(super) fn with_capacity(capacity: usize) -> Self {
        Self {
            pool: Vec::with_capacity(capacity),
            blocks: Vec::with_capacity(capacity / BLOCK),
            free: Vec::new(),
            last: vec![0; BANDS],
        }
    }

    /// Adds `entry` to `band`; returns its place in the pool.
    #[inline]
    pub(super) fn push(&mut self, band: usize, entry: T) -> usize {
        let mut last = self.last[band];
        if last == 0 || self.blocks[last as usize - 1].fill == BLOCK as u32 {
            let block = Block { prev: last, fill: 0 };
            let id = match self.free.pop() {
                Some(id) => {
                    self.blocks[id as usize] = block;
                    id
                }
                None => {
                    self.pool.resize(self.pool.len() + BLOCK, entry);
                    self.blocks.push(block);
                    self.blocks.len() as u32 - 1
                }
            };
            last = id + 1;
            self.last[band] = last;
        }
        let block = &mut self.blocks[last as usize - 1];
        let place = (last as usize - 1) * BLOCK + block.fill as usize;
        block.fill += 1;
        self.pool[place] = entry;
        place
    }

    /// The entry at `place`.
    #[inline]
    pub(super) fn get(&self, place: usize) -> T {
        self.pool[place]
    }

    /// Overwrites the entry at `place`, which must stay in the same band.
    #[inline]
    pub(super) fn replace(&mut self, place: usize, entry: T) {
        self.pool[place] = entry;
    }

    /// Removes the entry at `place` of `band` by moving the band's last entry there; returns
    /// the moved entry, or None when the removed one was the last.
    #[inline]
    pub(super) fn swap_remove(&mut self, band: usize, place: usize) -> Option<T> {
        let id = self.last[band] as usize - 1;
        let block = &mut self.blocks[id];
        block.fill -= 1;
        let last = id * BLOCK + block.fill as usize;
        if block.fill == 0 {
            self.last[band] = block.prev;
            self.free.push(id as u32);
        }
        (last != place).then(|| {
            let moved = self.pool[last];
            self.pool[place] = moved;
            moved
        })
    }

    /// The highest band below `floor` that holds entries.
    pub(super) fn highest_below(&self, floor: usize) -> Option<usize> {
        (0..floor).rev().find(|&band| self.last[band] != 0)
    }

    /// Appends the entries of `band` to `out`, in no particular order, and empties the band.
    pub(super) fn drain_into(&mut self, band: usize, out: &mut Vec<T>) {
        let mut last = std::mem::take(&mut self.last[band]);
        while last != 0 {
            let id = last as usize - 1;
            let Block { prev, fill } = self.blocks[id];
            out.extend_from_slice(&self.pool[id * BLOCK..id * BLOCK + fill as usize]);
            self.free.push(id as u32);
            last = prev;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeMap;

    #[derive(Debug, Clone)]
    enum Op {
        Push(usize),
        Remove(usize),
        Drain(usize),
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            8 => (0usize..3).prop_map(Op::Push),
            3 => any::<usize>().prop_map(Op::Remove),
            1 => (0usize..3).prop_map(Op::Drain),
        ]
    }

    proptest! {
        /// Against a map from place to (band, entry), over enough entries to chain blocks and
        /// reuse freed ones: every place holds what the map says, removal moves the band's
        /// last entry into the hole, and a drain gives exactly the band's entries.
        #[test]
        fn places_hold_their_entries_through_pushes_removals_and_drains(
            ops in prop::collection::vec(op(), 0..3000),
        ) {
            let mut buckets = Buckets::new();
            let mut live: BTreeMap<usize, (usize, u32)> = BTreeMap::new();
            for (value, op) in ops.into_iter().enumerate() {
                let value = value as u32;
                match op {
                    Op::Push(band) => {
                        let place = buckets.push(band, value);
                        prop_assert!(live.insert(place, (band, value)).is_none(), "place {} reused while live", place);
                    }
                    Op::Remove(k) if !live.is_empty() => {
                        let (&place, &(band, _)) = live.iter().nth(k % live.len()).unwrap();
                        live.remove(&place);
                        let moved = buckets.swap_remove(band, place);
                        if let Some(moved) = moved {
                            let (&from, &(from_band, _)) = live.iter().find(|(_, (_, v))| *v == moved).unwrap();
                            prop_assert_eq!(from_band, band);
                            live.remove(&from);
                            live.insert(place, (band, moved));
                        }
                    }
                    Op::Remove(_) => {}
                    Op::Drain(band) => {
                        let mut out = Vec::new();
                        buckets.drain_into(band, &mut out);
                        out.sort_unstable();
                        let mut expected: Vec<u32> = live.values().filter(|&&(b, _)| b == band).map(|&(_, v)| v).collect();
                        expected.sort_unstable();
                        prop_assert_eq!(out, expected);
                        live.retain(|_, &mut (b, _)| b != band);
                    }
                }
                for (&place, &(_, value)) in &live {
                    prop_assert_eq!(buckets.get(place), value);
                }
                prop_assert_eq!(buckets.highest_below(3), live.values().map(|&(b, _)| b).max());
            }
        }
    }
}
