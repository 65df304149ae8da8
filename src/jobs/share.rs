//! Fair shares: each client holds at most its share of the jobs a server takes (running and
//! queued), and a client past its share of the workers lets others' waiting jobs run first
//! ([`super::dispatch`]), so one caller's long jobs cannot make everyone else wait, while a
//! worker never idles when a job waits.

use std::collections::HashMap;
use std::fmt;
use std::sync::{Arc, Mutex};

/// Whom a job is charged to: an API key's name, or a client address.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Client(Arc<str>);

impl Client {
    /// The name, e.g. `key:3f2a9c01b2d4` or `addr:127.0.0.1`.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl From<String> for Client {
    fn from(name: String) -> Self {
        Self(name.into())
    }
}

impl fmt::Debug for Client {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&*self.0, f)
    }
}

/// The shares, and what each client holds now.
pub(super) struct Shares {
    /// Jobs one client runs before other clients' waiting jobs go first.
    pub(super) workers: usize,
    /// Jobs one client may have running and queued.
    pub(super) jobs: usize,
    /// Jobs each client holds, running and queued.
    held: Arc<Mutex<HashMap<Client, usize>>>,
}

/// A client's seat in its share: one job charged to it until dropped.
pub(super) struct Seat {
    client: Client,
    held: Arc<Mutex<HashMap<Client, usize>>>,
}

impl Shares {
    /// Each client gets `share` (in (0, 1]) of `workers` and of `workers + queue` jobs,
    /// rounded up, so that every client can run at least one job.
    pub(super) fn new(share: f64, workers: usize, queue: usize) -> Self {
        let of = |n: usize| ((share * n as f64).ceil() as usize).clamp(1, n.max(1));
        Self { workers: of(workers), jobs: of(workers + queue), held: Arc::default() }
    }

    /// Charges a job to `client`, or says how many it holds when that is its share.
    pub(super) fn charge(&self, client: &Client) -> Result<Seat, usize> {
        let mut held = self.held.lock().expect("shares poisoned");
        let jobs = held.entry(client.clone()).or_default();
        if *jobs >= self.jobs {
            return Err(*jobs);
        }
        *jobs += 1;
        Ok(Seat { client: client.clone(), held: self.held.clone() })
    }

    /// Jobs `client` holds now.
    #[cfg(test)]
    pub(super) fn held(&self, client: &Client) -> usize {
        self.held.lock().expect("shares poisoned").get(client).copied().unwrap_or(0)
    }
}

impl Seat {
    /// The client the job is charged to.
    pub(super) fn client(&self) -> &Client {
        &self.client
    }
}

impl Drop for Seat {
    fn drop(&mut self) {
        uncount(&mut self.held.lock().expect("shares poisoned"), &self.client);
    }
}

/// Takes one off `client`'s count, forgetting a client whose count reaches 0, so that the map
/// holds only clients that hold something.
fn uncount(counts: &mut HashMap<Client, usize>, client: &Client) {
    if let Some(n) = counts.get_mut(client) {
        *n -= 1;
        if *n == 0 {
            counts.remove(client);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_client_holds_at_most_its_share_and_gets_it_back_as_jobs_end() {
        let shares = Shares::new(0.5, 2, 8);
        assert_eq!((shares.workers, shares.jobs), (1, 5));
        let (a, b) = (Client::from("addr:a".to_owned()), Client::from("addr:b".to_owned()));
        let mut charges: Vec<Seat> = (0..5).map(|_| shares.charge(&a).unwrap()).collect();
        assert_eq!(shares.charge(&a).err(), Some(5));
        assert!(shares.charge(&b).is_ok(), "another client is not refused");
        charges.pop();
        assert!(shares.charge(&a).is_ok());
        drop(charges);
        assert_eq!(shares.held(&a), 0);
    }

    #[test]
    fn every_client_may_run_a_job_however_small_the_share() {
        let shares = Shares::new(0.01, 1, 0);
        assert_eq!((shares.workers, shares.jobs), (1, 1));
        let whole = Shares::new(1.0, 4, 60);
        assert_eq!((whole.workers, whole.jobs), (4, 64));
    }
}
