//! The set of constrained edges a mesh carries (see [`super::constrained`] for how they are
//! made and kept): plain data, so that the mesh can hold it without knowing how it is built.

use std::collections::HashSet;

/// The constrained edges, each as its two vertex ids.
#[derive(Debug, Clone, Default)]
pub(super) struct Constraints(HashSet<u64>);

fn key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    (u64::from(lo) << 32) | u64::from(hi)
}

impl Constraints {
    /// Whether the edge between `a` and `b` is constrained.
    #[inline]
    pub(super) fn holds(&self, a: u32, b: u32) -> bool {
        !self.0.is_empty() && self.0.contains(&key(a, b))
    }

    /// Constrains the edge between `a` and `b`.
    pub(super) fn insert(&mut self, a: u32, b: u32) {
        self.0.insert(key(a, b));
    }

    /// The edge `a`–`b`, if constrained, is now `a`–`m` and `m`–`b`.
    #[inline]
    pub(super) fn split(&mut self, a: u32, b: u32, m: u32) {
        if !self.0.is_empty() && self.0.remove(&key(a, b)) {
            self.0.insert(key(a, m));
            self.0.insert(key(m, b));
        }
    }

    pub(super) fn len(&self) -> usize {
        self.0.len()
    }

    pub(super) fn iter(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.0.iter().map(|&k| ((k >> 32) as u32, k as u32))
    }
}
