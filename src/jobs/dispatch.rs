//! The server's workers, handed to waiting jobs so that none idles while a job waits, with
//! the clients' shares deciding who runs next.
//!
//! A job runs at once when a worker is free, whatever its client already runs: a client alone
//! on the server may use every worker. When all are busy, jobs wait in arrival order, and a
//! freed worker goes to the oldest waiting job whose client runs fewer than its share; only when
//! every waiting client is at its share does it go to the oldest job. So a client's second job
//! never waits behind an idle worker, and a client that arrives at a busy server is the next to
//! run instead of queueing behind another's backlog.
//!
//! And it need not wait for a job to end: a job that waits while its client runs fewer than
//! its share asks a worker of the client furthest over its share to yield
//! ([`Worker::is_asked_to_yield`]). That job gives its worker back at its next step
//! (`worker::JobObserver`, within an insertion or a solve), pauses where it is, holding its
//! memory, and waits for a worker again ahead of every other waiting job
//! ([`Worker::take_turn`]); its result is the same bytes, only later.

use super::share::Client;
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::oneshot;

/// The workers and what waits for them.
pub(super) struct Dispatch {
    /// Jobs one client runs before another client's waiting job goes first.
    share: usize,
    /// A std Mutex: held for a few map and queue operations, never across an `.await`.
    state: Mutex<State>,
}

struct State {
    workers: usize,
    /// Oldest first (a paused job goes first). A waiter whose job was cancelled stays until a
    /// freed worker finds its receiver gone and passes on.
    waiting: VecDeque<(Client, oneshot::Sender<Worker>)>,
    /// The workers held, by id: whose, and the flag that asks it to yield. How many are free
    /// and how many each client runs are counted from it.
    held: Vec<(u64, Client, Arc<AtomicBool>)>,
    /// The next worker's id.
    next_id: u64,
}

impl State {
    /// Workers no job holds.
    fn free(&self) -> usize {
        self.workers - self.held.len()
    }

    /// Workers `client`'s jobs hold.
    fn runs(&self, client: &Client) -> usize {
        self.held.iter().filter(|(_, c, _)| c == client).count()
    }

    /// A worker handed to `client`, listed.
    fn grant(&mut self, dispatch: &Arc<Dispatch>, client: &Client) -> Worker {
        self.next_id += 1;
        let yield_asked = Arc::new(AtomicBool::new(false));
        self.held.push((self.next_id, client.clone(), yield_asked.clone()));
        Worker { dispatch: Some(dispatch.clone()), client: client.clone(), id: self.next_id, yield_asked }
    }

    /// Forgets worker `id`.
    fn ungrant(&mut self, id: u64) {
        self.held.retain(|(held, ..)| *held != id);
    }

    /// Asks one more worker to yield, while fewer are asked than the waiting clients below
    /// `share` are short of it (each counts the workers it lacks, at most its waiting jobs):
    /// one of the client furthest over its share (the newest of its workers).
    fn ask_to_yield(&mut self, share: usize) {
        let runs = |c: &Client| self.runs(c);
        let mut short: HashMap<&Client, usize> = HashMap::new();
        for (c, _) in self.waiting.iter().filter(|(c, tx)| !tx.is_closed() && runs(c) < share) {
            let lacks = short.entry(c).or_insert(0);
            *lacks = (*lacks + 1).min(share - runs(c));
        }
        let under: usize = short.values().sum();
        let asked = self.held.iter().filter(|(.., flag)| flag.load(Ordering::Relaxed)).count();
        if asked >= under {
            return;
        }
        // `max_by_key` keeps the last of equals: the newest worker of that client.
        let over = self
            .held
            .iter()
            .filter(|(_, c, flag)| runs(c) > share && !flag.load(Ordering::Relaxed))
            .max_by_key(|(_, c, _)| runs(c));
        if let Some((.., flag)) = over {
            flag.store(true, Ordering::Relaxed);
        }
    }
}

/// One worker, held by a job's client until dropped.
pub(super) struct Worker {
    /// `None` once the worker has been taken back without being released (a grant that found
    /// its job gone).
    dispatch: Option<Arc<Dispatch>>,
    client: Client,
    id: u64,
    /// Set when a job of a client below its share waits for this worker.
    yield_asked: Arc<AtomicBool>,
}

impl Worker {
    /// Whether a waiting job of a client below its share asks for this worker: one load, for
    /// the engine's step loop.
    pub(super) fn is_asked_to_yield(&self) -> bool {
        self.yield_asked.load(Ordering::Relaxed)
    }

    /// Gives this worker back (to the job that asked for it) and waits for one again, ahead
    /// of every job that has not started. `None` only if the dispatcher went away first.
    pub(super) async fn take_turn(mut self) -> Option<Worker> {
        let dispatch = self.dispatch.take()?;
        let client = self.client.clone();
        let waiting = {
            let mut state = dispatch.lock();
            let (tx, rx) = oneshot::channel();
            state.waiting.push_front((client.clone(), tx));
            rx
        };
        dispatch.release(self.id);
        waiting.await.ok()
    }
}

impl Dispatch {
    /// `workers` workers, of which one client runs `share` before others' jobs go first.
    pub(super) fn new(workers: usize, share: usize) -> Arc<Self> {
        let state = State { workers, waiting: VecDeque::new(), held: Vec::new(), next_id: 0 };
        Arc::new(Self { share, state: Mutex::new(state) })
    }

    /// Workers free now: none while any job waits.
    pub(super) fn free(&self) -> usize {
        self.lock().free()
    }

    /// A worker for a job of `client`: at once when one is free, else when the order above
    /// comes to it. `None` only if the dispatcher went away first.
    pub(super) async fn acquire(self: &Arc<Self>, client: &Client) -> Option<Worker> {
        let waiting = {
            let mut state = self.lock();
            if state.free() > 0 {
                return Some(state.grant(self, client));
            }
            let (tx, rx) = oneshot::channel();
            state.waiting.push_back((client.clone(), tx));
            state.ask_to_yield(self.share);
            rx
        };
        waiting.await.ok()
    }

    fn release(self: &Arc<Self>, id: u64) {
        let mut state = self.lock();
        state.ungrant(id);
        let share = self.share;
        loop {
            let under_share = state.waiting.iter().position(|(c, _)| state.runs(c) < share);
            let Some((next, tx)) = under_share
                .or((!state.waiting.is_empty()).then_some(0))
                .and_then(|i| state.waiting.remove(i))
            else {
                return;
            };
            let worker = state.grant(self, &next);
            match tx.send(worker) {
                Ok(()) => {
                    // Still a job under its share waiting? Another worker is asked.
                    state.ask_to_yield(share);
                    return;
                }
                // The job stopped waiting (cancelled): take the worker back, without the
                // release its drop would make under this lock, and look again.
                Err(mut unclaimed) => {
                    unclaimed.dispatch = None;
                    state.ungrant(unclaimed.id);
                }
            }
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().expect("dispatch poisoned")
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        if let Some(dispatch) = self.dispatch.take() {
            dispatch.release(self.id);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::future::Future;
    use std::pin::pin;
    use std::task::{Context, Poll, Waker};

    fn client(name: &str) -> Client {
        Client::from(format!("addr:{name}"))
    }

    /// Polls `future` once: its output if it is ready now.
    fn now<F: Future>(future: F) -> Option<F::Output> {
        match pin!(future).poll(&mut Context::from_waker(Waker::noop())) {
            Poll::Ready(output) => Some(output),
            Poll::Pending => None,
        }
    }

    #[tokio::test]
    async fn a_client_alone_uses_every_idle_worker_beyond_its_share() {
        let dispatch = Dispatch::new(2, 1);
        let a = client("a");
        let first = now(dispatch.acquire(&a)).flatten().expect("a free worker");
        let second = now(dispatch.acquire(&a)).flatten().expect("the other worker, past a's share of one");
        assert_eq!(dispatch.free(), 0);
        let mut third = pin!(dispatch.acquire(&a));
        assert!(now(third.as_mut()).is_none(), "no worker is free");
        drop(first);
        let third = third.await.expect("the freed worker goes to the waiting job");
        assert_eq!(dispatch.free(), 0);
        drop(second);
        assert_eq!(dispatch.free(), 1);
        drop(third);
        assert_eq!(dispatch.free(), 2);
    }

    #[tokio::test]
    async fn a_freed_worker_goes_first_to_a_client_under_its_share() {
        let dispatch = Dispatch::new(2, 1);
        let (a, b) = (client("a"), client("b"));
        let running = [dispatch.acquire(&a).await.unwrap(), dispatch.acquire(&a).await.unwrap()];
        // a's third job waits first, b's only job after it.
        let a_waits = tokio::spawn({
            let (dispatch, a) = (dispatch.clone(), a.clone());
            async move { dispatch.acquire(&a).await.map(drop) }
        });
        tokio::task::yield_now().await;
        let b_waits = tokio::spawn({
            let (dispatch, b) = (dispatch.clone(), b.clone());
            async move { dispatch.acquire(&b).await }
        });
        tokio::task::yield_now().await;
        let [one, two] = running;
        drop(one);
        let b_worker = b_waits.await.unwrap().expect("b runs next: it runs nothing, a runs its share");
        assert!(!a_waits.is_finished(), "a's job still waits");
        drop(two);
        a_waits.await.unwrap().expect("then a's job runs");
        drop(b_worker);
        assert_eq!(dispatch.free(), 2);
    }

    #[tokio::test]
    async fn a_cancelled_waiter_passes_its_turn_on() {
        let dispatch = Dispatch::new(1, 1);
        let (a, b) = (client("a"), client("b"));
        let running = dispatch.acquire(&a).await.unwrap();
        let mut cancelled = Box::pin(dispatch.acquire(&b));
        assert!(now(cancelled.as_mut()).is_none());
        let mut waiting = pin!(dispatch.acquire(&a));
        assert!(now(waiting.as_mut()).is_none());
        drop(cancelled);
        drop(running);
        let worker = waiting.await.expect("the worker skipped the cancelled job");
        assert_eq!(dispatch.free(), 0);
        drop(worker);
        assert_eq!(dispatch.free(), 1, "nothing leaked");
    }

    #[tokio::test]
    async fn a_client_below_its_share_asks_the_client_furthest_over_to_yield_and_runs_first() {
        let dispatch = Dispatch::new(2, 1);
        let (a, b) = (client("a"), client("b"));
        let running = [dispatch.acquire(&a).await.unwrap(), dispatch.acquire(&a).await.unwrap()];
        // a's own third job waits without asking anything of a's runs.
        let mut a_third = Box::pin(dispatch.acquire(&a));
        assert!(now(a_third.as_mut()).is_none());
        assert!(running.iter().all(|w| !w.is_asked_to_yield()), "a alone keeps every worker");
        // b runs nothing and waits: one of a's two is asked, the newest.
        let mut b_waits = Box::pin(dispatch.acquire(&b));
        assert!(now(b_waits.as_mut()).is_none());
        let [first, second] = running;
        assert!(!first.is_asked_to_yield() && second.is_asked_to_yield());
        // It yields at its next step: b runs, and the paused run waits first in line.
        let mut resumed = Box::pin(second.take_turn());
        assert!(now(resumed.as_mut()).is_none());
        let b_worker = b_waits.await.expect("b takes the yielded worker");
        assert!(!b_worker.is_asked_to_yield() && !first.is_asked_to_yield(), "a is at its share now");
        drop(b_worker);
        let resumed = resumed.await.expect("the paused run goes on before a's third job starts");
        assert!(now(a_third.as_mut()).is_none());
        drop(first);
        let third = a_third.await.unwrap();
        drop((resumed, third));
        assert_eq!(dispatch.free(), 2, "nothing leaked");
    }

    #[tokio::test]
    async fn no_more_runs_are_asked_than_jobs_wait_below_their_share() {
        let dispatch = Dispatch::new(3, 1);
        let (a, b) = (client("a"), client("b"));
        let running: Vec<Worker> = vec![
            dispatch.acquire(&a).await.unwrap(),
            dispatch.acquire(&a).await.unwrap(),
            dispatch.acquire(&a).await.unwrap(),
        ];
        let mut b_one = Box::pin(dispatch.acquire(&b));
        assert!(now(b_one.as_mut()).is_none());
        let mut b_two = Box::pin(dispatch.acquire(&b));
        assert!(now(b_two.as_mut()).is_none());
        // b lacks one worker of its share, however many of its jobs wait: one run is asked.
        assert_eq!(running.iter().filter(|w| w.is_asked_to_yield()).count(), 1);
        drop(b_two);
        let mut running = running;
        let asked = running.iter().position(Worker::is_asked_to_yield).unwrap();
        let mut paused = Box::pin(running.remove(asked).take_turn());
        assert!(now(paused.as_mut()).is_none(), "the paused run waits");
        let b_worker = b_one.await.unwrap();
        drop((running, b_worker, paused));
    }
}
