//! Finished meshes: a byte-bounded in-memory cache, optionally backed by files that survive a
//! restart.
//!
//! moka rather than a hand-made LRU: it bounds the cache by a weigher (the body's bytes), is
//! safe to share between threads, and is widely used. A disk entry is one file,
//! `{id}.mesh`: a header line `meshfit-cache-v1 <sha256 of body> <stats JSON>` and the body.
//! The checksum is verified on every read; a file that fails it is deleted and recomputed,
//! never served.

use bytes::Bytes;
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

const MAGIC: &str = "meshfit-cache-v1";

/// A finished mesh: the document as sent, and its stats for status responses.
#[derive(Debug, Clone, PartialEq)]
pub struct Finished {
    /// The mesh document, `{"id", "vertices", "triangles", "stats"}`.
    pub body: Bytes,
    /// The document's `stats` member.
    pub stats: serde_json::Value,
}

/// Where a lookup found its entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hit {
    /// In memory.
    Memory,
    /// On disk, verified, and now in memory too.
    Disk,
}

/// The cache of finished meshes by job id.
#[derive(Clone)]
pub struct Cache {
    memory: moka::sync::Cache<String, Arc<Finished>>,
    dir: Option<PathBuf>,
}

impl Cache {
    /// A cache of at most `bytes` bytes of bodies in memory, mirrored in `dir` if given.
    ///
    /// # Errors
    /// When `dir` cannot be created.
    pub fn new(bytes: u64, dir: Option<PathBuf>) -> std::io::Result<Self> {
        if let Some(dir) = &dir {
            std::fs::create_dir_all(dir)?;
        }
        let memory = moka::sync::Cache::builder()
            .max_capacity(bytes)
            .weigher(|_: &String, f: &Arc<Finished>| u32::try_from(f.body.len()).unwrap_or(u32::MAX))
            .build();
        Ok(Self { memory, dir })
    }

    /// The entry for `id` from memory, without touching the disk.
    pub fn get_memory(&self, id: &str) -> Option<Arc<Finished>> {
        self.memory.get(id)
    }

    /// The entry for `id`, from memory or else from disk. Blocking: call it off the async
    /// workers when a disk is configured.
    pub fn get(&self, id: &str) -> Option<(Arc<Finished>, Hit)> {
        if let Some(f) = self.memory.get(id) {
            return Some((f, Hit::Memory));
        }
        let path = self.path(id)?;
        let finished = match read_entry(&path) {
            Ok(Some(f)) => Arc::new(f),
            Ok(None) => return None,
            Err(why) => {
                tracing::warn!(id, %why, "discarding corrupt cache file");
                let _ = std::fs::remove_file(&path);
                return None;
            }
        };
        self.memory.insert(id.to_owned(), finished.clone());
        Some((finished, Hit::Disk))
    }

    /// Whether a disk mirror is configured (lookups may then block).
    pub fn has_disk(&self) -> bool {
        self.dir.is_some()
    }

    /// Stores an entry in memory and, if configured, on disk (blocking).
    pub fn insert(&self, id: &str, finished: Arc<Finished>) {
        if let Some(path) = self.path(id)
            && let Err(e) = write_entry(&path, &finished)
        {
            tracing::warn!(id, error = %e, "could not write cache file");
        }
        self.memory.insert(id.to_owned(), finished);
    }

    /// Bytes of bodies held in memory.
    pub fn memory_bytes(&self) -> u64 {
        self.memory.run_pending_tasks();
        self.memory.weighted_size()
    }

    fn path(&self, id: &str) -> Option<PathBuf> {
        // Ids are our own hex digests; anything else never names a file.
        let safe = id.len() == 64 && id.bytes().all(|b| b.is_ascii_hexdigit());
        self.dir.as_ref().filter(|_| safe).map(|d| d.join(format!("{id}.mesh")))
    }
}

fn checksum(body: &[u8]) -> String {
    format!("{:x}", Sha256::digest(body))
}

fn write_entry(path: &Path, f: &Finished) -> std::io::Result<()> {
    // Write to a temporary name of our own and rename, so a crash never leaves a half file
    // under the id and two writers (threads or processes sharing the directory) never
    // interleave.
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let unique = format!("{}.{}.tmp", std::process::id(), NEXT.fetch_add(1, Ordering::Relaxed));
    let tmp = path.with_extension(unique);
    let written = (|| {
        let mut file = std::io::BufWriter::new(std::fs::File::create_new(&tmp)?);
        writeln!(file, "{MAGIC} {} {}", checksum(&f.body), f.stats)?;
        file.write_all(&f.body)?;
        file.into_inner()?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

fn read_entry(path: &Path) -> Result<Option<Finished>, String> {
    let data = match std::fs::read(path) {
        Ok(d) => d,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e.to_string()),
    };
    let newline = data.iter().position(|&b| b == b'\n').ok_or("no header line")?;
    let header = std::str::from_utf8(&data[..newline]).map_err(|_| "header is not UTF-8")?;
    let mut parts = header.splitn(3, ' ');
    if parts.next() != Some(MAGIC) {
        return Err("unknown format".into());
    }
    let sum = parts.next().ok_or("no checksum")?;
    let stats = serde_json::from_str(parts.next().ok_or("no stats")?).map_err(|e| e.to_string())?;
    let body = Bytes::copy_from_slice(&data[newline + 1..]);
    if checksum(&body) != sum {
        return Err("checksum mismatch".into());
    }
    Ok(Some(Finished { body, stats }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry() -> Arc<Finished> {
        Arc::new(Finished {
            body: Bytes::from_static(b"{\"id\":1}"),
            stats: serde_json::json!({"vertices": 4}),
        })
    }

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("meshfit-cache-test-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    const ID: &str = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";

    #[test]
    fn an_entry_written_to_disk_is_read_back_by_a_new_cache() {
        let dir = temp_dir("roundtrip");
        Cache::new(1 << 20, Some(dir.clone())).unwrap().insert(ID, entry());
        let (got, hit) = Cache::new(1 << 20, Some(dir.clone())).unwrap().get(ID).unwrap();
        assert_eq!((got, hit), (entry(), Hit::Disk));
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_corrupt_file_is_deleted_and_reported_as_a_miss() {
        let dir = temp_dir("corrupt");
        Cache::new(1 << 20, Some(dir.clone())).unwrap().insert(ID, entry());
        let path = dir.join(format!("{ID}.mesh"));
        let mut data = std::fs::read(&path).unwrap();
        *data.last_mut().unwrap() ^= 1;
        std::fs::write(&path, data).unwrap();
        assert_eq!(Cache::new(1 << 20, Some(dir.clone())).unwrap().get(ID), None);
        assert!(!path.exists(), "the corrupt file should be gone");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn ids_that_are_not_our_digests_never_touch_the_disk() {
        let dir = temp_dir("ids");
        let cache = Cache::new(1 << 20, Some(dir.clone())).unwrap();
        assert_eq!(cache.path("../../etc/passwd"), None);
        std::fs::remove_dir_all(dir).unwrap();
    }
}
