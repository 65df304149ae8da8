//! The server's workers, handed to waiting jobs so that none idles while a job waits, with
//! the clients' shares deciding who runs next.
//!
//! A job runs at once when a worker is free, whatever its client already runs: a client alone
//! on the server may use every worker. When all are busy, jobs wait in arrival order, and a
//! freed worker goes to the oldest waiting job whose client runs fewer than its share; only when
//! every waiting client is at its share does it go to the oldest job. So a client's second job
//! never waits behind an idle worker, and a client that arrives at a busy server is the next to
//! run instead of queueing behind another's backlog. Running jobs are never preempted.

use super::share::{Client, uncount};
use std::collections::{HashMap, VecDeque};
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
    free: usize,
    running: HashMap<Client, usize>,
    /// Oldest first. A waiter whose job was cancelled stays until a freed worker finds its
    /// receiver gone and passes on.
    waiting: VecDeque<(Client, oneshot::Sender<Worker>)>,
}

/// One worker, held by a job's client until dropped.
pub(super) struct Worker {
    /// `None` once the worker has been taken back without being released (a grant that found
    /// its job gone).
    dispatch: Option<Arc<Dispatch>>,
    client: Client,
}

impl Dispatch {
    /// `workers` workers, of which one client runs `share` before others' jobs go first.
    pub(super) fn new(workers: usize, share: usize) -> Arc<Self> {
        let state = State { free: workers, running: HashMap::new(), waiting: VecDeque::new() };
        Arc::new(Self { share, state: Mutex::new(state) })
    }

    /// Workers free now: none while any job waits.
    pub(super) fn free(&self) -> usize {
        self.lock().free
    }

    /// A worker for a job of `client`: at once when one is free, else when the order above
    /// comes to it. `None` only if the dispatcher went away first.
    pub(super) async fn acquire(self: &Arc<Self>, client: &Client) -> Option<Worker> {
        let waiting = {
            let mut state = self.lock();
            if state.free > 0 {
                state.free -= 1;
                *state.running.entry(client.clone()).or_default() += 1;
                return Some(Worker { dispatch: Some(self.clone()), client: client.clone() });
            }
            let (tx, rx) = oneshot::channel();
            state.waiting.push_back((client.clone(), tx));
            rx
        };
        waiting.await.ok()
    }

    fn release(self: &Arc<Self>, client: &Client) {
        let mut state = self.lock();
        uncount(&mut state.running, client);
        let share = self.share;
        loop {
            let under_share =
                state.waiting.iter().position(|(c, _)| state.running.get(c).is_none_or(|&n| n < share));
            let Some((next, tx)) = under_share
                .or((!state.waiting.is_empty()).then_some(0))
                .and_then(|i| state.waiting.remove(i))
            else {
                state.free += 1;
                return;
            };
            *state.running.entry(next.clone()).or_default() += 1;
            match tx.send(Worker { dispatch: Some(self.clone()), client: next.clone() }) {
                Ok(()) => return,
                // The job stopped waiting (cancelled): take the worker back, without the
                // release its drop would make under this lock, and look again.
                Err(mut unclaimed) => {
                    unclaimed.dispatch = None;
                    uncount(&mut state.running, &next);
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
            dispatch.release(&self.client);
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
}
