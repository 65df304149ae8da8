//! Families: per family of requests (see [`crate::spec::JobKeys`]), the cached run that went
//! furthest, the one that answers the most smaller requests by replay.

use crate::result::RunResult;

/// How many families remember their furthest run.
const FAMILIES_KEPT: u64 = 100_000;

/// Per family, the cached run that went furthest, and its number of steps.
pub(super) struct Families {
    runs: moka::sync::Cache<String, (String, usize)>,
}

impl Families {
    /// No family known yet.
    pub(super) fn new() -> Self {
        Self { runs: moka::sync::Cache::new(FAMILIES_KEPT) }
    }

    /// Remembers cached run `id` as its family's furthest if it traced more steps than the
    /// one known.
    pub(super) fn note(&self, family: &str, id: &str, result: &RunResult) {
        let Some(steps) = result.trace.as_ref().map(|t| t.splits.len()) else { return };
        if self.runs.get(family).is_none_or(|(_, known)| steps >= known) {
            self.runs.insert(family.to_owned(), (id.to_owned(), steps));
        }
    }

    /// The id of the family's furthest cached run, if known.
    pub(super) fn furthest(&self, family: &str) -> Option<String> {
        self.runs.get(family).map(|(run, _)| run)
    }
}
