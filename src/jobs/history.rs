//! Who submitted which job, and when: what `GET /v1/jobs` lists, newest first.
//!
//! A job is shared by every identical request, so the list is of submissions, one per
//! client and job (the latest), each numbered in the order they came: the number is the
//! list's cursor, stable while later submissions arrive. Entries older than the retention,
//! or past [`SUBMISSIONS_KEPT`], are dropped oldest first.

use super::share::Client;
use std::collections::VecDeque;
use std::sync::Mutex;
use std::time::{Duration, SystemTime};

/// The most submissions remembered, whatever their age: the memory the list may take.
pub const SUBMISSIONS_KEPT: usize = 10_000;

/// One client's submission of one job.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Submission {
    /// Its place in the order submissions came, from 1: the list's cursor.
    pub seq: u64,
    /// The job.
    pub id: String,
    /// Who submitted it.
    pub client: Client,
    /// When (the client's latest submission of the job).
    pub at: SystemTime,
}

/// The submissions this replica took.
pub(super) struct History {
    retention: Duration,
    entries: Mutex<Entries>,
}

#[derive(Default)]
struct Entries {
    /// Oldest first.
    list: VecDeque<Submission>,
    last: u64,
}

impl History {
    /// An empty history keeping submissions for `retention`.
    pub(super) fn new(retention: Duration) -> Self {
        Self { retention, entries: Mutex::default() }
    }

    /// Notes that `client` submitted job `id` at `at`; an earlier submission of the same job by
    /// the same client moves to the front.
    pub(super) fn note(&self, id: &str, client: &Client, at: SystemTime) {
        let mut entries = self.entries.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        entries.list.retain(|s| !(s.id == id && s.client == *client));
        entries.last += 1;
        let seq = entries.last;
        entries.list.push_back(Submission { seq, id: id.to_owned(), client: client.clone(), at });
        Self::prune(&mut entries, self.retention, at);
    }

    /// Submissions numbered below `before` (all when `None`), of `client` alone when given,
    /// newest first.
    pub(super) fn newest(
        &self,
        client: Option<&Client>,
        before: Option<u64>,
        now: SystemTime,
    ) -> Vec<Submission> {
        let mut entries = self.entries.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        Self::prune(&mut entries, self.retention, now);
        entries
            .list
            .iter()
            .rev()
            .filter(|s| before.is_none_or(|b| s.seq < b) && client.is_none_or(|c| s.client == *c))
            .cloned()
            .collect()
    }

    fn prune(entries: &mut Entries, retention: Duration, now: SystemTime) {
        let expired = |s: &Submission| now.duration_since(s.at).is_ok_and(|age| age > retention);
        while entries.list.len() > SUBMISSIONS_KEPT || entries.list.front().is_some_and(expired) {
            entries.list.pop_front();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn client(name: &str) -> Client {
        Client::from(name.to_owned())
    }

    #[test]
    fn the_newest_come_first_a_resubmission_moves_up_and_each_client_sees_its_own() {
        let history = History::new(Duration::from_secs(60));
        let t0 = SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000);
        let at = |s: u64| t0 + Duration::from_secs(s);
        history.note("a", &client("key:1"), at(0));
        history.note("b", &client("key:1"), at(1));
        history.note("a", &client("key:2"), at(2));
        history.note("a", &client("key:1"), at(3));
        let ids = |list: Vec<Submission>| list.into_iter().map(|s| (s.id, s.seq)).collect::<Vec<_>>();
        assert_eq!(
            ids(history.newest(Some(&client("key:1")), None, at(4))),
            [("a".into(), 4), ("b".into(), 2)]
        );
        assert_eq!(ids(history.newest(Some(&client("key:2")), None, at(4))), [("a".into(), 3)]);
        assert_eq!(ids(history.newest(None, Some(3), at(4))), [("b".into(), 2)]);
        // Past the retention, the oldest go.
        assert_eq!(ids(history.newest(None, None, at(62))), [("a".into(), 4), ("a".into(), 3)]);
    }

    #[test]
    fn at_most_the_kept_number_are_remembered() {
        let history = History::new(Duration::from_secs(3600));
        let t0 = SystemTime::UNIX_EPOCH;
        for k in 0..SUBMISSIONS_KEPT + 5 {
            history.note(&format!("{k}"), &client("addr:1"), t0);
        }
        let all = history.newest(None, None, t0);
        assert_eq!(all.len(), SUBMISSIONS_KEPT);
        assert_eq!(all.last().unwrap().id, "5", "the five oldest went");
    }
}
