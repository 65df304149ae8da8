//! [`Peers`] for a replica on its own: there is no store, so every operation fails as if the
//! store were away, and the replica acts alone, as every replica does while its store is
//! away. A single process thus runs the same protocol code as a replica among others, down
//! its tested "store away" paths, and nothing it does leaves the process.

use super::store::{Peers, Result, Unavailable};
use super::wire::{Acquired, Asked, Control, Kept, Message, Posting, Shelf, Take};
use std::time::Duration;
use tokio::sync::broadcast;

/// No other replica: the registry's peers until [`Jobs::shared`](crate::jobs::Jobs::shared)
/// gives it a store.
pub(crate) struct Alone;

fn none<T>() -> Result<T> {
    Err(Unavailable("this replica shares with no other".into()))
}

#[async_trait::async_trait]
impl Peers for Alone {
    fn lease(&self) -> Duration {
        // Nobody takes a job over: any lease is as long as the job.
        Duration::from_secs(3600)
    }

    fn token(&self) -> String {
        String::new()
    }

    fn is_mine(&self, _: &str) -> bool {
        true
    }

    fn is_shared(&self) -> bool {
        false
    }

    fn is_up(&self) -> bool {
        false
    }

    fn messages(&self) -> broadcast::Receiver<Message> {
        // Closed at once: nobody else posts.
        broadcast::channel(1).1
    }

    async fn ping(&self) -> Result<()> {
        none()
    }

    async fn acquire(&self, _: &str, _: &str, _: Take) -> Result<Acquired> {
        none()
    }

    async fn renew(&self, _: &str, _: &str) -> Result<bool> {
        none()
    }

    async fn release(&self, _: &str, _: &str) -> Result<()> {
        none()
    }

    async fn holder(&self, _: &str) -> Result<Option<String>> {
        none()
    }

    async fn post(&self, _: &str, _: Option<&str>, _: &Posting) -> Result<bool> {
        none()
    }

    async fn posting(&self, _: &str) -> Result<Option<Posting>> {
        none()
    }

    async fn keep_spec(&self, _: &str, _: &[u8]) -> Result<bool> {
        none()
    }

    async fn kept_spec(&self, _: &str) -> Result<Option<Vec<u8>>> {
        none()
    }

    async fn pending(&self) -> Result<Vec<String>> {
        none()
    }

    async fn is_pending(&self, _: &str) -> Result<bool> {
        none()
    }

    async fn forget(&self, _: &str) -> Result<()> {
        none()
    }

    async fn control(&self, _: &str, _: Control) -> Result<()> {
        none()
    }

    async fn asked(&self, _: &str) -> Result<Asked> {
        none()
    }

    async fn result(&self, _: &str, _: Kept) -> Result<Option<Vec<u8>>> {
        none()
    }

    async fn keep_result(&self, _: &str, _: Kept, _: &[u8]) -> Result<bool> {
        none()
    }

    async fn keep_file(&self, _: Shelf, _: &str, _: &[u8]) -> Result<bool> {
        none()
    }

    async fn file(&self, _: Shelf, _: &str) -> Result<Option<Vec<u8>>> {
        none()
    }

    async fn drop_file(&self, _: Shelf, _: &str) -> Result<()> {
        none()
    }

    async fn append_log(&self, _: &str, _: u64, _: &[Vec<u8>], _: Duration) -> Result<Option<Vec<Vec<u8>>>> {
        none()
    }

    async fn log(&self, _: &str, _: u64) -> Result<Vec<Vec<u8>>> {
        none()
    }
}
