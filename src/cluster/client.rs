//! [`Cluster`]: the replica's handle on Redis, and its [`Peers`] implementation.

use super::keys::{
    ACQUIRE, APPEND_LOG, CONTROL, DROPPED, EVENTS, PENDING, POST, RELEASE, RENEW, key, result_key,
};
use super::link::Inner;
use super::listen;
use crate::config::Redis;
use crate::jobs::peers::{
    Acquired, Asked, Control, Kept, Message, Peers, Posting, Result, Shelf, Take, Unavailable,
};
use redis::AsyncCommands;
use redis::aio::ConnectionManager;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;
use tokio::sync::broadcast;

/// The connection to Redis, shared by every task of a replica. Cheap to clone.
#[derive(Clone)]
pub struct Cluster {
    inner: Arc<Inner>,
}

impl Cluster {
    /// A client of the Redis at `url`, as `settings` say; connects lazily, so a replica starts (and
    /// serves alone) while Redis is down. Counts failed commands in `errors`.
    ///
    /// # Errors
    /// When the URL is not a Redis URL.
    pub fn connect(
        url: &str,
        settings: Redis,
        errors: prometheus_client::metrics::counter::Counter,
    ) -> std::result::Result<Self, redis::RedisError> {
        let client = redis::Client::open(url)?;
        let config = redis::aio::ConnectionManagerConfig::new()
            .set_connection_timeout(Some(Duration::from_secs(1)))
            // Long enough for a result of MESHFIT_REDIS_MAX_BYTES; a Redis that stops answering
            // is found by the ping, which has a timeout of its own.
            .set_response_timeout(Some(Duration::from_secs(30)))
            .set_number_of_retries(2)
            .set_max_delay(Duration::from_millis(500));
        let conn = ConnectionManager::new_lazy_with_config(client.clone(), config.clone())?;
        let bulk = ConnectionManager::new_lazy_with_config(client.clone(), config)?;
        let host = rustix::system::uname().nodename().to_string_lossy().into_owned();
        let started = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
        let replica = format!("{host}/{}/{}", std::process::id(), started.as_micros());
        let (messages, _) = broadcast::channel(1024);
        let inner = Arc::new(Inner {
            conn,
            bulk,
            settings,
            replica,
            runs: AtomicU64::new(0),
            up: AtomicBool::new(false),
            errors,
            messages,
        });
        tokio::spawn(listen::run(client, Arc::downgrade(&inner)));
        Ok(Self { inner })
    }

    /// This replica's name, as its leases hold it.
    pub fn replica(&self) -> &str {
        &self.inner.replica
    }

    /// Notes the outcome of a command in `up` and the error count.
    fn note<T>(&self, result: redis::RedisResult<T>) -> Result<T> {
        self.inner.note(result)
    }

    /// The connection, while Redis answers. While it does not, commands fail at once instead
    /// of each waiting out a connection attempt: the replica serves alone until a ping (at each
    /// sweep for orphaned jobs) or the subscription finds Redis again.
    fn conn(&self) -> Result<ConnectionManager> {
        self.while_up(&self.inner.conn)
    }

    /// [`Cluster::conn`] for results and specs.
    fn bulk(&self) -> Result<ConnectionManager> {
        self.while_up(&self.inner.bulk)
    }

    fn while_up(&self, conn: &ConnectionManager) -> Result<ConnectionManager> {
        match self.is_up() {
            true => Ok(conn.clone()),
            false => Err(Unavailable("redis is not connected".into())),
        }
    }

    fn ttl_ms(&self) -> u64 {
        self.inner.settings.ttl.as_millis() as u64
    }
}

#[async_trait::async_trait]
impl Peers for Cluster {
    fn lease(&self) -> Duration {
        self.inner.settings.lease
    }

    fn token(&self) -> String {
        format!("{}#{}", self.inner.replica, self.inner.runs.fetch_add(1, Ordering::Relaxed))
    }

    fn is_mine(&self, token: &str) -> bool {
        token.strip_prefix(&self.inner.replica).is_some_and(|rest| rest.starts_with('#'))
    }

    fn is_shared(&self) -> bool {
        true
    }

    fn is_up(&self) -> bool {
        self.inner.up.load(Ordering::Relaxed)
    }

    fn messages(&self) -> broadcast::Receiver<Message> {
        self.inner.messages.subscribe()
    }

    // Within a second, whether or not Redis answered last time.
    async fn ping(&self) -> Result<()> {
        let mut conn = self.inner.conn.clone();
        let ping = redis::cmd("PING");
        let pong = ping.query_async::<String>(&mut conn);
        match tokio::time::timeout(Duration::from_secs(1), pong).await {
            Ok(pong) => self.note(pong).map(drop),
            Err(_) => Err(self.inner.unreachable(std::io::Error::from(std::io::ErrorKind::TimedOut).into())),
        }
    }

    async fn result(&self, id: &str, kept: Kept) -> Result<Option<Vec<u8>>> {
        let got = self.bulk()?.get(result_key(kept, id)).await;
        self.note(got)
    }

    async fn keep_file(&self, shelf: Shelf, id: &str, bytes: &[u8]) -> Result<bool> {
        if bytes.len() as u64 > self.inner.settings.max_bytes {
            return Ok(false);
        }
        let key = key(shelf.name(), id);
        let set = match shelf {
            // An upload stays until it is deleted: a replica serving it from memory never reads
            // it back, so no read would renew a time to live.
            Shelf::Dataset => self.bulk()?.set::<_, _, ()>(key, bytes).await,
            Shelf::Tile => self.bulk()?.pset_ex::<_, _, ()>(key, bytes, self.ttl_ms()).await,
        };
        self.note(set).map(|()| true)
    }

    async fn file(&self, shelf: Shelf, id: &str) -> Result<Option<Vec<u8>>> {
        let key = key(shelf.name(), id);
        let got = match shelf {
            Shelf::Dataset => self.bulk()?.get(key).await,
            Shelf::Tile => self.bulk()?.get_ex(key, redis::Expiry::PX(self.ttl_ms())).await,
        };
        self.note(got)
    }

    async fn drop_file(&self, shelf: Shelf, id: &str) -> Result<()> {
        let done = redis::pipe()
            .del(key(shelf.name(), id))
            .ignore()
            .publish(DROPPED, listen::dropped(shelf, id))
            .ignore()
            .query_async::<()>(&mut self.conn()?)
            .await;
        self.note(done)
    }

    async fn keep_result(&self, id: &str, kept: Kept, bytes: &[u8]) -> Result<bool> {
        if bytes.len() as u64 > self.inner.settings.max_bytes {
            return Ok(false);
        }
        let set = self.bulk()?.pset_ex::<_, _, ()>(result_key(kept, id), bytes, self.ttl_ms()).await;
        self.note(set).map(|()| true)
    }

    async fn acquire(&self, id: &str, token: &str, take: Take) -> Result<Acquired> {
        let lease = self.inner.settings.lease.as_millis() as u64;
        let held = ACQUIRE
            .key(key("lease", id))
            .key(key("cancel", id))
            .key(key("detach", id))
            .key(key("job", id))
            .arg(token)
            .arg(lease)
            .arg(u8::from(take == Take::Fresh))
            .invoke_async::<Option<String>>(&mut self.conn()?)
            .await;
        Ok(self.note(held)?.map_or(Acquired::Won, Acquired::Held))
    }

    async fn renew(&self, id: &str, token: &str) -> Result<bool> {
        let lease = self.inner.settings.lease.as_millis() as u64;
        let renewed =
            RENEW.key(key("lease", id)).arg(token).arg(lease).invoke_async::<i64>(&mut self.conn()?).await;
        self.note(renewed).map(|n| n == 1)
    }

    async fn release(&self, id: &str, token: &str) -> Result<()> {
        let released = RELEASE.key(key("lease", id)).arg(token).invoke_async::<i64>(&mut self.conn()?).await;
        self.note(released).map(drop)
    }

    async fn holder(&self, id: &str) -> Result<Option<String>> {
        let held = self.conn()?.get(key("lease", id)).await;
        self.note(held)
    }

    async fn post(&self, id: &str, token: Option<&str>, posting: &Posting) -> Result<bool> {
        let json = serde_json::to_string(posting).expect("a posting serializes");
        let written = POST
            .key(key("job", id))
            .key(key("lease", id))
            .arg(token.unwrap_or_default())
            .arg(&json)
            .arg(self.ttl_ms())
            .arg(EVENTS)
            .arg(listen::event(id, &json))
            .invoke_async::<i64>(&mut self.conn()?)
            .await;
        self.note(written).map(|n| n == 1)
    }

    async fn posting(&self, id: &str) -> Result<Option<Posting>> {
        let got = self.conn()?.get::<_, Option<String>>(key("job", id)).await;
        Ok(self.note(got)?.and_then(|json| serde_json::from_str(&json).ok()))
    }

    async fn keep_spec(&self, id: &str, spec: &[u8]) -> Result<bool> {
        if spec.len() as u64 > self.inner.settings.max_bytes {
            return Ok(false);
        }
        let done = redis::pipe()
            .atomic()
            .pset_ex(key("spec", id), spec, self.ttl_ms())
            .ignore()
            .sadd(PENDING, id)
            .ignore()
            .query_async::<()>(&mut self.bulk()?)
            .await;
        self.note(done).map(|()| true)
    }

    async fn kept_spec(&self, id: &str) -> Result<Option<Vec<u8>>> {
        let got = self.bulk()?.get(key("spec", id)).await;
        self.note(got)
    }

    async fn pending(&self) -> Result<Vec<String>> {
        let members = self.conn()?.smembers(PENDING).await;
        self.note(members)
    }

    async fn is_pending(&self, id: &str) -> Result<bool> {
        let member = self.conn()?.sismember(PENDING, id).await;
        self.note(member)
    }

    async fn forget(&self, id: &str) -> Result<()> {
        let done = redis::pipe()
            .srem(PENDING, id)
            .ignore()
            .del(&[key("spec", id), key("cancel", id), key("detach", id)])
            .ignore()
            .query_async::<()>(&mut self.conn()?)
            .await;
        self.note(done)
    }

    // The key is kept for three leases: past that the run has either read it or been taken
    // over by a run that reads it.
    async fn control(&self, id: &str, what: Control) -> Result<()> {
        let name = match what {
            Control::Cancel => key("cancel", id),
            Control::Detach => key("detach", id),
        };
        let keep = 3 * self.inner.settings.lease.as_millis() as u64;
        let done = redis::pipe()
            .pset_ex(name, 1, keep)
            .ignore()
            .publish(CONTROL, listen::control(id, what))
            .ignore()
            .query_async::<()>(&mut self.conn()?)
            .await;
        self.note(done)
    }

    async fn asked(&self, id: &str) -> Result<Asked> {
        let asked = redis::pipe()
            .exists(key("cancel", id))
            .exists(key("detach", id))
            .query_async::<(bool, bool)>(&mut self.conn()?)
            .await;
        self.note(asked).map(|(cancel, detach)| Asked { cancel, detach })
    }

    async fn append_log(
        &self,
        id: &str,
        at: u64,
        entries: &[Vec<u8>],
        keep: Duration,
    ) -> Result<Option<Vec<Vec<u8>>>> {
        let mut script = APPEND_LOG.key(key("log", id));
        script.arg(at).arg(keep.as_millis() as u64);
        for entry in entries {
            script.arg(entry.as_slice());
        }
        let answer = script.invoke_async::<(u8, Vec<Vec<u8>>)>(&mut self.bulk()?).await;
        self.note(answer).map(|(appended, missed)| (appended == 0).then_some(missed))
    }

    async fn log(&self, id: &str, from: u64) -> Result<Vec<Vec<u8>>> {
        let entries = self.bulk()?.lrange(key("log", id), from as isize, -1).await;
        self.note(entries)
    }
}
