//! Replicas that share results and jobs through Redis (`MESHFIT_REDIS_URL`).
//!
//! This module is the transport: keys, leases, records and messages, in bytes and wire types.
//! What a replica does with them (follow a job another replica runs, take over one whose
//! replica died) is in [`crate::jobs`].
//!
//! redis-rs rather than a hand-written client: its `ConnectionManager` multiplexes every
//! command over one connection and reconnects by itself after Redis comes back, which is
//! exactly the behaviour a replica needs when Redis goes away.
//!
//! | key | holds | expires |
//! |---|---|---|
//! | `meshfit:result:{id}` | a finished result, compact and checksummed | `MESHFIT_REDIS_TTL_MS` |
//! | `meshfit:partial:{id}` | a result a time limit stopped (never a new request's answer) | same |
//! | `meshfit:job:{id}` | the job's [`Record`] as JSON | same |
//! | `meshfit:lease:{id}` | the replica running the job | `MESHFIT_REDIS_LEASE_MS`, renewed |
//! | `meshfit:request:{id}` | the request body, so another replica can take the job over | same as results |
//! | `meshfit:pending` | ids of jobs not finished, with a stored request | |
//! | `meshfit:cancel:{id}` | set by `DELETE` on any replica | same as results |
//!
//! Records go out on the channel `meshfit:events` as they change; `meshfit:control` carries
//! `cancel {id}` and `detach {id}` to the replica that runs the job.

mod listen;
mod record;

pub use listen::Message;
pub use record::Record;

use redis::AsyncCommands;
use redis::aio::ConnectionManager;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use tokio::sync::broadcast;

/// How replicas share through Redis.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Settings {
    /// `redis://host:port/db`.
    pub url: String,
    /// How long results, records and requests stay in Redis.
    pub ttl: Duration,
    /// The largest result (in its compact form) or request body stored; larger ones stay on
    /// the replica that made them.
    pub max_bytes: u64,
    /// How long a job's lease lasts without renewal: how soon another replica takes over a
    /// job whose replica died. Renewed every third of it.
    pub lease: Duration,
}

/// A request as a client sent it, kept so that another replica can run the job again.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    /// `mesh` or `solution`: what the body was read as.
    pub kind: String,
    /// The body's `Content-Type`.
    pub content_type: String,
    /// The body.
    pub body: bytes::Bytes,
}

/// What a control message asks of the replica running a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    /// Stop it.
    Cancel,
    /// Run it to the end even if its own clients leave: a client on another replica waits.
    Detach,
}

/// Why a Redis operation did not complete: the replica then acts on its own.
#[derive(Debug, thiserror::Error)]
#[error("redis: {0}")]
pub struct Unavailable(#[from] redis::RedisError);

type Result<T> = std::result::Result<T, Unavailable>;

/// The connection to Redis, shared by every task of a replica. Cheap to clone.
#[derive(Clone)]
pub struct Cluster {
    inner: Arc<Inner>,
}

struct Inner {
    conn: ConnectionManager,
    settings: Settings,
    /// This replica's name in leases: host, process and start time.
    replica: String,
    /// Whether the last command reached Redis.
    up: AtomicBool,
    errors: prometheus_client::metrics::counter::Counter,
    messages: broadcast::Sender<Message>,
}

const EVENTS: &str = "meshfit:events";
const CONTROL: &str = "meshfit:control";
const PENDING: &str = "meshfit:pending";

fn key(kind: &str, id: &str) -> String {
    format!("meshfit:{kind}:{id}")
}

/// Extends a lease if this replica holds it.
const RENEW: &str = r"if redis.call('get', KEYS[1]) == ARGV[1] then
  return redis.call('pexpire', KEYS[1], ARGV[2]) else return 0 end";

/// Deletes a lease if this replica holds it.
const RELEASE: &str = r"if redis.call('get', KEYS[1]) == ARGV[1] then
  return redis.call('del', KEYS[1]) else return 0 end";

impl Cluster {
    /// A client of the Redis at `settings.url`; connects lazily, so a replica starts (and
    /// serves alone) while Redis is down. Counts failed commands in `errors`.
    ///
    /// # Errors
    /// When the URL is not a Redis URL.
    pub fn connect(
        settings: Settings,
        errors: prometheus_client::metrics::counter::Counter,
    ) -> std::result::Result<Self, redis::RedisError> {
        let client = redis::Client::open(settings.url.as_str())?;
        let config = redis::aio::ConnectionManagerConfig::new()
            .set_connection_timeout(Some(Duration::from_secs(1)))
            .set_response_timeout(Some(Duration::from_secs(5)))
            .set_number_of_retries(2)
            .set_max_delay(Duration::from_millis(500));
        let conn = ConnectionManager::new_lazy_with_config(client.clone(), config)?;
        let host = rustix::system::uname().nodename().to_string_lossy().into_owned();
        let started = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
        let replica = format!("{host}/{}/{}", std::process::id(), started.as_micros());
        let (messages, _) = broadcast::channel(1024);
        let inner = Arc::new(Inner { conn, settings, replica, up: AtomicBool::new(false), errors, messages });
        tokio::spawn(listen::run(client, Arc::downgrade(&inner)));
        Ok(Self { inner })
    }

    /// The settings in force.
    pub fn settings(&self) -> &Settings {
        &self.inner.settings
    }

    /// This replica's name, as its leases hold it.
    pub fn replica(&self) -> &str {
        &self.inner.replica
    }

    /// Whether the last command reached Redis.
    pub fn is_up(&self) -> bool {
        self.inner.up.load(Ordering::Relaxed)
    }

    /// Messages from the other replicas (and this one), as they arrive.
    pub fn messages(&self) -> broadcast::Receiver<Message> {
        self.inner.messages.subscribe()
    }

    /// Notes the outcome of a command in `up` and the error count.
    fn note<T>(&self, result: redis::RedisResult<T>) -> Result<T> {
        self.inner.note(result)
    }

    /// The connection, while Redis answers. While it does not, commands fail at once instead
    /// of each waiting out a connection attempt: the replica serves alone until a ping (at each
    /// sweep for orphaned jobs) or the subscription finds Redis again.
    fn conn(&self) -> Result<ConnectionManager> {
        match self.is_up() {
            true => Ok(self.inner.conn.clone()),
            false => Err(Unavailable(std::io::Error::from(std::io::ErrorKind::NotConnected).into())),
        }
    }

    fn ttl_ms(&self) -> u64 {
        self.inner.settings.ttl.as_millis() as u64
    }

    /// Checks that Redis answers (whether or not it did last time).
    ///
    /// # Errors
    /// When it does not.
    pub async fn ping(&self) -> Result<()> {
        let pong = redis::cmd("PING").query_async::<String>(&mut self.inner.conn.clone()).await;
        self.note(pong).map(drop)
    }

    /// The stored result `id` in compact form (`partial`: one a time limit stopped).
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn result(&self, id: &str, partial: bool) -> Result<Option<Vec<u8>>> {
        let name = if partial { "partial" } else { "result" };
        let got = self.conn()?.get(key(name, id)).await;
        self.note(got)
    }

    /// Stores result `id` in compact form, unless it is larger than `max_bytes`; says whether
    /// it was stored.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn put_result(&self, id: &str, partial: bool, bytes: &[u8]) -> Result<bool> {
        if bytes.len() as u64 > self.inner.settings.max_bytes {
            return Ok(false);
        }
        let name = if partial { "partial" } else { "result" };
        let set = self.conn()?.pset_ex::<_, _, ()>(key(name, id), bytes, self.ttl_ms()).await;
        self.note(set).map(|()| true)
    }

    /// Takes the lease on job `id` if nobody holds it; says whether this replica now does.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn acquire(&self, id: &str) -> Result<bool> {
        let lease = self.inner.settings.lease.as_millis() as u64;
        let set = redis::cmd("SET")
            .arg(key("lease", id))
            .arg(&self.inner.replica)
            .arg("NX")
            .arg("PX")
            .arg(lease)
            .query_async::<Option<String>>(&mut self.conn()?)
            .await;
        self.note(set).map(|ok| ok.is_some())
    }

    /// Extends this replica's lease on `id`; false when it no longer holds it.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn renew(&self, id: &str) -> Result<bool> {
        let lease = self.inner.settings.lease.as_millis() as u64;
        let renewed = redis::Script::new(RENEW)
            .key(key("lease", id))
            .arg(&self.inner.replica)
            .arg(lease)
            .invoke_async::<i64>(&mut self.conn()?)
            .await;
        self.note(renewed).map(|n| n == 1)
    }

    /// Gives up this replica's lease on `id`, so another may take the job at once.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn release(&self, id: &str) -> Result<()> {
        let released = redis::Script::new(RELEASE)
            .key(key("lease", id))
            .arg(&self.inner.replica)
            .invoke_async::<i64>(&mut self.conn()?)
            .await;
        self.note(released).map(drop)
    }

    /// Whether some replica holds the lease on `id`.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn is_leased(&self, id: &str) -> Result<bool> {
        let exists = self.conn()?.exists(key("lease", id)).await;
        self.note(exists)
    }

    /// Stores job `id`'s record and sends it to every replica.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn put_record(&self, id: &str, record: &Record) -> Result<()> {
        let json = serde_json::to_string(record).expect("a record serializes");
        let message = listen::event(id, &json);
        let done = redis::pipe()
            .pset_ex(key("job", id), &json, self.ttl_ms())
            .ignore()
            .publish(EVENTS, message)
            .ignore()
            .query_async::<()>(&mut self.conn()?)
            .await;
        self.note(done)
    }

    /// Job `id`'s record, if any replica stored one (a record that does not parse, from
    /// another version, counts as none).
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn record(&self, id: &str) -> Result<Option<Record>> {
        let got = self.conn()?.get::<_, Option<String>>(key("job", id)).await;
        Ok(self.note(got)?.and_then(|json| serde_json::from_str(&json).ok()))
    }

    /// Keeps the request of job `id` and lists the job as pending, so that another replica
    /// can take it over; says whether it was kept (not when larger than `max_bytes`).
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn put_request(&self, id: &str, request: &Request) -> Result<bool> {
        if request.body.len() as u64 > self.inner.settings.max_bytes {
            return Ok(false);
        }
        let name = key("request", id);
        let done = redis::pipe()
            .atomic()
            .hset_multiple(
                &name,
                &[
                    ("kind", request.kind.as_bytes()),
                    ("content_type", request.content_type.as_bytes()),
                    ("body", &request.body[..]),
                ],
            )
            .ignore()
            .pexpire(&name, self.ttl_ms() as i64)
            .ignore()
            .sadd(PENDING, id)
            .ignore()
            .query_async::<()>(&mut self.conn()?)
            .await;
        self.note(done).map(|()| true)
    }

    /// The request of job `id`, if kept.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn request(&self, id: &str) -> Result<Option<Request>> {
        let got = redis::cmd("HMGET")
            .arg(key("request", id))
            .arg(&["kind", "content_type", "body"])
            .query_async::<(Option<String>, Option<String>, Option<Vec<u8>>)>(&mut self.conn()?)
            .await;
        Ok(match self.note(got)? {
            (Some(kind), Some(content_type), Some(body)) => {
                Some(Request { kind, content_type, body: body.into() })
            }
            _ => None,
        })
    }

    /// The jobs listed as pending.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn pending(&self) -> Result<Vec<String>> {
        let members = self.conn()?.smembers(PENDING).await;
        self.note(members)
    }

    /// Takes job `id` off the pending list and drops its request: it finished.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn forget(&self, id: &str) -> Result<()> {
        let done = redis::pipe()
            .srem(PENDING, id)
            .ignore()
            .del(key("request", id))
            .ignore()
            .query_async::<()>(&mut self.conn()?)
            .await;
        self.note(done)
    }

    /// Asks the replica running job `id` to act. A cancellation is also kept as a key, which
    /// that replica checks at each renewal: a message can be missed, a key cannot.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn control(&self, id: &str, what: Control) -> Result<()> {
        let mut pipe = redis::pipe();
        if what == Control::Cancel {
            pipe.pset_ex(key("cancel", id), 1, self.ttl_ms()).ignore();
        }
        pipe.publish(CONTROL, listen::control(id, what)).ignore();
        let done = pipe.query_async::<()>(&mut self.conn()?).await;
        self.note(done)
    }

    /// Whether a client asked for job `id` to be cancelled.
    ///
    /// # Errors
    /// When Redis does not answer.
    pub async fn is_cancelled(&self, id: &str) -> Result<bool> {
        let exists = self.conn()?.exists(key("cancel", id)).await;
        self.note(exists)
    }
}

impl Inner {
    /// Notes a command's outcome: Redis is up after an answer, down after a failure to reach
    /// it. An error Redis itself answered (out of memory, say) leaves it up: it is there.
    fn note<T>(&self, result: redis::RedisResult<T>) -> Result<T> {
        match result {
            Ok(value) => {
                if !self.up.swap(true, Ordering::Relaxed) {
                    tracing::info!("redis reachable");
                }
                Ok(value)
            }
            Err(e) => {
                self.errors.inc();
                let unreachable = e.is_io_error()
                    || e.is_timeout()
                    || e.is_connection_dropped()
                    || e.is_connection_refusal()
                    || e.is_unrecoverable_error();
                if unreachable && self.up.swap(false, Ordering::Relaxed) {
                    tracing::warn!(error = %e, "redis unreachable; serving from this replica alone");
                } else if !unreachable {
                    tracing::warn!(error = %e, "redis refused a command");
                }
                Err(Unavailable(e))
            }
        }
    }
}
