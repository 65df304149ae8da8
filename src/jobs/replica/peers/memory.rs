//! [`Peers`] in memory: several replicas of one process over a shared [`Bus`], with the
//! semantics the Redis store has (leases that lapse on tokio's clock, postings only from the
//! lease's holder, messages to every replica, operations that fail at once while the store
//! is known to be away, until a ping finds it), and switches a test turns to take the store
//! away from one replica ([`Replica::cut`]) or from all ([`Bus::set_up`]), or to lose the
//! messages that ask a run to act ([`Bus::lose_controls`]). Every operation yields first, as
//! a round trip would, so that concurrent submissions interleave.

use super::store::{Peers, Result, Unavailable};
use super::wire::{Acquired, Asked, Control, Kept, Message, Posting, Shelf, Take};
use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::broadcast;
use tokio::time::Instant;

/// The store every replica of a test shares. Cheap to clone.
#[derive(Clone)]
pub(crate) struct Bus {
    state: Arc<Mutex<State>>,
    messages: broadcast::Sender<Message>,
    lease: Duration,
    /// The largest request or result kept, as `MESHFIT_REDIS_MAX_BYTES`.
    max_bytes: usize,
    /// Whether control messages are lost on the way (their marks are kept).
    lose_controls: Arc<AtomicBool>,
}

#[derive(Default)]
struct State {
    /// Whether the store answers at all.
    down: bool,
    leases: HashMap<String, (String, Instant)>,
    postings: HashMap<String, Posting>,
    specs: HashMap<String, Vec<u8>>,
    pending: BTreeSet<String>,
    /// What was asked of a job's run, until when.
    marks: HashMap<(String, Control), Instant>,
    results: HashMap<(String, Kept), Vec<u8>>,
    files: HashMap<(Shelf, String), Vec<u8>>,
    /// Logs, with when each is dropped.
    logs: HashMap<String, (Vec<Vec<u8>>, Instant)>,
}

impl State {
    fn holder(&self, id: &str) -> Option<&str> {
        self.leases.get(id).filter(|(_, until)| *until > Instant::now()).map(|(token, _)| token.as_str())
    }
}

impl Bus {
    /// A store whose leases last `lease` and that keeps requests and results up to
    /// `max_bytes`.
    pub(crate) fn new(lease: Duration, max_bytes: usize) -> Self {
        let (messages, _) = broadcast::channel(1024);
        Self { state: Arc::default(), messages, lease, max_bytes, lose_controls: Arc::default() }
    }

    /// A replica named `name` on this bus.
    pub(crate) fn replica(&self, name: &str) -> Arc<Replica> {
        Arc::new(Replica {
            bus: self.clone(),
            name: name.to_owned(),
            runs: AtomicU64::new(0),
            up: AtomicBool::new(true),
            cut: AtomicBool::new(false),
        })
    }

    /// Takes the store away from every replica, or brings it back.
    pub(crate) fn set_up(&self, up: bool) {
        self.state().down = !up;
    }

    /// Loses every control message from now on (`true`), or delivers them again.
    pub(crate) fn lose_controls(&self, lose: bool) {
        self.lose_controls.store(lose, Ordering::SeqCst);
    }

    /// Whether job `id` is listed as pending.
    pub(crate) fn is_listed(&self, id: &str) -> bool {
        self.state().pending.contains(id)
    }

    /// Job `id`'s posting, whether or not the store is up.
    pub(crate) fn posting_of(&self, id: &str) -> Option<Posting> {
        self.state().postings.get(id).cloned()
    }

    /// Whether a whole result of job `id` is stored.
    pub(crate) fn has_result(&self, id: &str) -> bool {
        self.state().results.contains_key(&(id.to_owned(), Kept::Whole))
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().expect("bus poisoned")
    }
}

/// One replica's handle on the bus.
pub(crate) struct Replica {
    bus: Bus,
    name: String,
    runs: AtomicU64,
    /// Whether the last operation reached the store.
    up: AtomicBool,
    /// Whether this replica is cut off from the store (a network split, or a replica that
    /// died while its tasks linger).
    cut: AtomicBool,
}

impl Replica {
    /// Cuts this replica off from the store, or connects it again.
    pub(crate) fn cut(&self, cut: bool) {
        self.cut.store(cut, Ordering::SeqCst);
    }

    /// The store's state, when this replica reaches it: after a yield, as a round trip; at
    /// once refused while the last operation failed, unless `probe` (a ping), as `Cluster`
    /// refuses commands until a ping finds Redis again.
    async fn reach(&self, probe: bool) -> Result<std::sync::MutexGuard<'_, State>> {
        tokio::task::yield_now().await;
        let refused = || Unavailable(format!("{} cannot reach the bus", self.name));
        if !probe && !self.up.load(Ordering::SeqCst) {
            return Err(refused());
        }
        let state = self.bus.state();
        let reached = !state.down && !self.cut.load(Ordering::SeqCst);
        self.up.store(reached, Ordering::SeqCst);
        if reached { Ok(state) } else { Err(refused()) }
    }

    fn send(&self, message: Message) {
        if matches!(message, Message::Control(..)) && self.bus.lose_controls.load(Ordering::SeqCst) {
            return;
        }
        // No receiver is fine: no replica listens yet.
        let _ = self.bus.messages.send(message);
    }
}

#[async_trait::async_trait]
impl Peers for Replica {
    fn lease(&self) -> Duration {
        self.bus.lease
    }

    fn token(&self) -> String {
        format!("{}#{}", self.name, self.runs.fetch_add(1, Ordering::Relaxed))
    }

    fn is_mine(&self, token: &str) -> bool {
        token.strip_prefix(&self.name).is_some_and(|rest| rest.starts_with('#'))
    }

    fn is_shared(&self) -> bool {
        true
    }

    fn is_up(&self) -> bool {
        self.up.load(Ordering::SeqCst)
    }

    fn messages(&self) -> broadcast::Receiver<Message> {
        self.bus.messages.subscribe()
    }

    async fn ping(&self) -> Result<()> {
        self.reach(true).await.map(drop)
    }

    async fn acquire(&self, id: &str, token: &str, take: Take) -> Result<Acquired> {
        let mut state = self.reach(false).await?;
        if let Some(holder) = state.holder(id) {
            return Ok(Acquired::Held(holder.to_owned()));
        }
        state.leases.insert(id.to_owned(), (token.to_owned(), Instant::now() + self.bus.lease));
        if take == Take::Fresh {
            state.postings.remove(id);
            state.marks.retain(|(job, _), _| job != id);
        }
        Ok(Acquired::Won)
    }

    async fn renew(&self, id: &str, token: &str) -> Result<bool> {
        let mut state = self.reach(false).await?;
        if state.holder(id) != Some(token) {
            return Ok(false);
        }
        state.leases.insert(id.to_owned(), (token.to_owned(), Instant::now() + self.bus.lease));
        Ok(true)
    }

    async fn release(&self, id: &str, token: &str) -> Result<()> {
        let mut state = self.reach(false).await?;
        if state.holder(id) == Some(token) {
            state.leases.remove(id);
        }
        Ok(())
    }

    async fn holder(&self, id: &str) -> Result<Option<String>> {
        Ok(self.reach(false).await?.holder(id).map(str::to_owned))
    }

    async fn post(&self, id: &str, token: Option<&str>, posting: &Posting) -> Result<bool> {
        let mut state = self.reach(false).await?;
        if state.holder(id).unwrap_or_default() != token.unwrap_or_default() {
            return Ok(false);
        }
        state.postings.insert(id.to_owned(), posting.clone());
        drop(state);
        self.send(Message::Posted(id.to_owned(), Box::new(posting.clone())));
        Ok(true)
    }

    async fn posting(&self, id: &str) -> Result<Option<Posting>> {
        Ok(self.reach(false).await?.postings.get(id).cloned())
    }

    async fn keep_spec(&self, id: &str, spec: &[u8]) -> Result<bool> {
        if spec.len() > self.bus.max_bytes {
            return Ok(false);
        }
        let mut state = self.reach(false).await?;
        state.specs.insert(id.to_owned(), spec.to_vec());
        state.pending.insert(id.to_owned());
        Ok(true)
    }

    async fn kept_spec(&self, id: &str) -> Result<Option<Vec<u8>>> {
        Ok(self.reach(false).await?.specs.get(id).cloned())
    }

    async fn pending(&self) -> Result<Vec<String>> {
        Ok(self.reach(false).await?.pending.iter().cloned().collect())
    }

    async fn is_pending(&self, id: &str) -> Result<bool> {
        Ok(self.reach(false).await?.pending.contains(id))
    }

    async fn forget(&self, id: &str) -> Result<()> {
        let mut state = self.reach(false).await?;
        state.pending.remove(id);
        state.specs.remove(id);
        state.marks.retain(|(job, _), _| job != id);
        Ok(())
    }

    async fn control(&self, id: &str, what: Control) -> Result<()> {
        let mut state = self.reach(false).await?;
        state.marks.insert((id.to_owned(), what), Instant::now() + 3 * self.bus.lease);
        drop(state);
        self.send(Message::Control(id.to_owned(), what));
        Ok(())
    }

    async fn asked(&self, id: &str) -> Result<Asked> {
        let state = self.reach(false).await?;
        let now = Instant::now();
        let marked = |what| state.marks.get(&(id.to_owned(), what)).is_some_and(|until| *until > now);
        Ok(Asked { cancel: marked(Control::Cancel), detach: marked(Control::Detach) })
    }

    async fn result(&self, id: &str, kept: Kept) -> Result<Option<Vec<u8>>> {
        Ok(self.reach(false).await?.results.get(&(id.to_owned(), kept)).cloned())
    }

    async fn keep_result(&self, id: &str, kept: Kept, bytes: &[u8]) -> Result<bool> {
        if bytes.len() > self.bus.max_bytes {
            return Ok(false);
        }
        let mut state = self.reach(false).await?;
        state.results.insert((id.to_owned(), kept), bytes.to_vec());
        Ok(true)
    }

    async fn keep_file(&self, shelf: Shelf, id: &str, bytes: &[u8]) -> Result<bool> {
        if bytes.len() > self.bus.max_bytes {
            return Ok(false);
        }
        self.reach(false).await?.files.insert((shelf, id.to_owned()), bytes.to_vec());
        Ok(true)
    }

    async fn file(&self, shelf: Shelf, id: &str) -> Result<Option<Vec<u8>>> {
        Ok(self.reach(false).await?.files.get(&(shelf, id.to_owned())).cloned())
    }

    async fn drop_file(&self, shelf: Shelf, id: &str) -> Result<()> {
        self.reach(false).await?.files.remove(&(shelf, id.to_owned()));
        self.send(Message::Dropped(shelf, id.to_owned()));
        Ok(())
    }

    async fn append_log(
        &self,
        id: &str,
        at: u64,
        entries: &[Vec<u8>],
        keep: Duration,
    ) -> Result<Option<Vec<Vec<u8>>>> {
        let mut state = self.reach(false).await?;
        let now = Instant::now();
        state.logs.retain(|_, (_, until)| *until > now);
        let (log, until) = state.logs.entry(id.to_owned()).or_insert_with(|| (Vec::new(), now));
        if log.len() as u64 != at {
            return Ok(Some(log.get(at as usize..).unwrap_or_default().to_vec()));
        }
        log.extend(entries.iter().cloned());
        *until = now + keep;
        Ok(None)
    }

    async fn log(&self, id: &str, from: u64) -> Result<Vec<Vec<u8>>> {
        let state = self.reach(false).await?;
        let log = state.logs.get(id).filter(|(_, until)| *until > Instant::now());
        Ok(log.and_then(|(log, _)| log.get(from as usize..)).unwrap_or_default().to_vec())
    }
}
