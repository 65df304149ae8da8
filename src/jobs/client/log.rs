//! A client job's log: everything said to the job that changed it, in order. Replicas that
//! share a store keep it there, so that any replica rebuilds the job from it and goes on
//! where another stopped; a replica alone keeps none.
//!
//! Entries are JSON (serde_json's `float_roundtrip` gives every f64 back bit for bit, which
//! the replay needs: the mesh depends on the values exactly as told).

use crate::geom::Point;
use crate::refine::asked::{Told, Values};
use serde::{Deserialize, Serialize};

/// One entry of a client job's log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum Entry {
    /// Entry 0: the request that made the job, and when, in ms since the Unix epoch.
    Made {
        /// When.
        at_ms: u64,
        /// The request, as `POST /v1/jobs` took it.
        request: serde_json::Value,
    },
    /// Entry 1 of a job made `from` another: that job's values, by point (x, y, F; `None`:
    /// failed).
    Seeded(Vec<(f64, f64, Option<f64>)>),
    /// Values told, by point id (`None`: failed).
    Told(Vec<(u64, Option<f64>)>),
    /// Batch `number`'s points, which take the next ids in order.
    Batch {
        /// Its number, from 2 (the corners are batch 1, and need no entry).
        number: u64,
        /// Its points.
        points: Vec<(f64, f64)>,
    },
    /// The caller cancelled the job.
    Cancelled,
}

impl Entry {
    /// The entry as the store keeps it.
    pub(super) fn encode(&self) -> Vec<u8> {
        serde_json::to_vec(self).expect("an entry serializes")
    }

    /// The entry that seeds a job with `values`, in one order whatever the map's.
    pub(super) fn seeded(values: &Values) -> Self {
        let mut seeded: Vec<_> = values.iter().map(|(p, told)| (p.x, p.y, told.value())).collect();
        seeded.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        Entry::Seeded(seeded)
    }

    /// The values of a `seeded` entry.
    pub(super) fn seeds(seeded: &[(f64, f64, Option<f64>)]) -> Values {
        let mut values = Values::new();
        for &(x, y, value) in seeded {
            values.tell(Point::new(x, y), Told::of(value));
        }
        values
    }

    /// The entry the store kept, if it reads (an entry of another version may not).
    pub(super) fn decode(bytes: &[u8]) -> Option<Self> {
        serde_json::from_slice(bytes).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_come_back_bit_for_bit() {
        let awkward = [0.1 + 0.2, -0.0, f64::MIN_POSITIVE, 1e308, 5e-324, std::f64::consts::PI];
        let entries = [
            Entry::Told(
                awkward.iter().enumerate().map(|(i, &v)| (i as u64, Some(v))).chain([(9, None)]).collect(),
            ),
            Entry::Batch { number: 2, points: awkward.iter().map(|&v| (v, -v)).collect() },
            Entry::Seeded(vec![(0.5, 0.25, None), (1.0 / 3.0, 2.0 / 3.0, Some(7.0))]),
            Entry::Cancelled,
        ];
        for entry in entries {
            let back = Entry::decode(&entry.encode()).expect("decodes");
            // PartialEq on f64 says -0.0 == 0.0: compare the bits through Debug of to_bits.
            assert_eq!(format!("{:?}", bits(&back)), format!("{:?}", bits(&entry)));
        }
        assert_eq!(Entry::decode(b"{\"unknown\": 1}"), None);
    }

    fn bits(entry: &Entry) -> Vec<u64> {
        match entry {
            Entry::Told(values) => {
                values.iter().flat_map(|&(id, v)| [id, v.map_or(1, f64::to_bits)]).collect()
            }
            Entry::Batch { number, points } => std::iter::once(*number)
                .chain(points.iter().flat_map(|p| [p.0.to_bits(), p.1.to_bits()]))
                .collect(),
            Entry::Seeded(values) => values
                .iter()
                .flat_map(|&(x, y, v)| [x.to_bits(), y.to_bits(), v.map_or(1, f64::to_bits)])
                .collect(),
            Entry::Made { at_ms, .. } => vec![*at_ms],
            Entry::Cancelled => vec![0],
        }
    }
}
