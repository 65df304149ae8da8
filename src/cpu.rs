//! CPU-bound work: on tokio's blocking pool, at a lower OS priority than the async workers.
//!
//! Parsing a large body, refining, replaying and encoding take whole cores for seconds. At the
//! same priority they share the cores evenly with the async workers, which then answer a
//! health check or a cached request tens of milliseconds late. At nice 10 a waking async
//! worker gets a core at once, and the work loses only what the answers take.

use std::cell::Cell;
use tokio::task::JoinHandle;

/// The nice value of threads that run CPU-bound work.
pub const NICE: i32 = 10;

thread_local! {
    static LOWERED: Cell<bool> = const { Cell::new(false) };
}

/// Lowers the calling thread's priority to [`NICE`] (never raises it), once per thread. A
/// blocking-pool thread only ever runs blocking work, so it keeps the lower priority for
/// everything it runs.
fn lower_priority() {
    LOWERED.with(|done| {
        if !done.replace(true) {
            // Linux's PRIO_PROCESS with a thread id reads and sets that thread's nice value.
            // Failure (a sandbox that forbids it) leaves the thread as it was: slower answers
            // to health checks, never wrong ones.
            let me = Some(rustix::thread::gettid());
            if rustix::process::getpriority_process(me).is_ok_and(|nice| nice < NICE) {
                let _ = rustix::process::setpriority_process(me, NICE);
            }
        }
    });
}

/// Runs `work` on the blocking pool at the lower priority.
pub fn spawn<F, R>(work: F) -> JoinHandle<R>
where
    F: FnOnce() -> R + Send + 'static,
    R: Send + 'static,
{
    tokio::task::spawn_blocking(move || {
        lower_priority();
        work()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn own_nice() -> i32 {
        rustix::process::getpriority_process(Some(rustix::thread::gettid())).unwrap()
    }

    #[tokio::test]
    async fn work_runs_at_the_lower_priority_and_the_async_worker_keeps_its_own() {
        let before = own_nice();
        // A process already nicer than NICE (a build under `nice -n 19`) is left as it is.
        let lowered = before.max(NICE);
        assert_eq!(spawn(own_nice).await.unwrap(), lowered);
        assert_eq!(spawn(own_nice).await.unwrap(), lowered, "a reused thread stays lowered");
        assert_eq!(own_nice(), before, "the caller's thread is untouched");
    }
}
