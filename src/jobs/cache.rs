//! Finished meshes: a byte-bounded in-memory cache, optionally backed by files that survive a
//! restart.
//!
//! moka rather than a hand-made LRU: it bounds the cache by a weigher (the result's bytes), is
//! safe to share between threads, and is widely used. A disk entry is one file, `{id}.mesh`,
//! in the checksummed compact form of [`compact`]. The checksum (over the stats and the id
//! too) is verified on every read; a file that fails it is deleted and recomputed, never
//! served. The files are bounded in bytes too: a second moka cache, plain LRU, indexes
//! them and deletes the least recently used file when they pass the limit.

use crate::result::{RunResult, compact};
use moka::notification::RemovalCause;
use moka::policy::EvictionPolicy;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::SystemTime;

/// Where a lookup found its entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hit {
    /// In memory.
    Memory,
    /// On disk, verified, and now in memory too.
    Disk,
}

/// Where finished meshes are kept, and how much of them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheSettings {
    /// Memory for finished meshes, part of the memory budget (`MESHFIT_CACHE_BYTES`).
    pub memory_bytes: u64,
    /// Where they are also written, to survive restarts (`MESHFIT_CACHE_DIR`).
    pub dir: Option<PathBuf>,
    /// Disk for those files (`MESHFIT_CACHE_DIR_BYTES`).
    pub dir_bytes: u64,
}

/// The cache of finished meshes by job id.
#[derive(Clone)]
pub struct Cache {
    memory: moka::sync::Cache<String, Arc<RunResult>>,
    /// Results of runs a time limit stopped, kept for the job's own clients (`GET /mesh`) but
    /// never the answer to a new request: how far such a run got depends on the machine.
    partial: moka::sync::Cache<String, Arc<RunResult>>,
    disk: Option<Disk>,
}

/// The directory of mesh files and an index of them by id, weighed by file size.
#[derive(Clone)]
struct Disk {
    dir: PathBuf,
    /// The most bytes of files to keep.
    limit: u64,
    files: moka::sync::Cache<String, u64>,
    /// Ids the index dropped for size, whose files are still to delete. moka may evict while
    /// any caller touches the index, async ones included, so the eviction listener only
    /// notes the id; [`Disk::evict`], called where blocking is fine, deletes the file.
    evicted: Arc<std::sync::Mutex<Vec<String>>>,
}

impl Cache {
    /// The cache `settings` describe.
    ///
    /// # Errors
    /// When its directory cannot be created or listed.
    pub fn open(settings: &CacheSettings) -> std::io::Result<Self> {
        Self::new(settings.memory_bytes, settings.dir.clone(), settings.dir_bytes)
    }

    /// A cache of at most `bytes` bytes of bodies in memory, mirrored in `dir` if given, where
    /// files take at most `dir_bytes` bytes.
    ///
    /// # Errors
    /// When `dir` cannot be created or listed.
    pub fn new(bytes: u64, dir: Option<PathBuf>, dir_bytes: u64) -> std::io::Result<Self> {
        let memory = moka::sync::Cache::builder().max_capacity(bytes).weigher(weight).build();
        let partial = moka::sync::Cache::builder().max_capacity(bytes / 4).weigher(weight).build();
        let disk = dir.map(|dir| Disk::open(dir, dir_bytes)).transpose()?;
        Ok(Self { memory, partial, disk })
    }

    /// The entry for `id` from memory, without reading the disk; a hit marks its file as used
    /// in the disk index.
    pub fn get_memory(&self, id: &str) -> Option<Arc<RunResult>> {
        let found = self.memory.get(id);
        if found.is_some()
            && let Some(disk) = &self.disk
        {
            // A mesh served from memory is in use: its file should not go first.
            disk.files.get(id);
        }
        found
    }

    /// The entry for `id`, from memory or else from disk. Blocking: call it off the async
    /// workers when a disk is configured.
    pub fn get(&self, id: &str) -> Option<(Arc<RunResult>, Hit)> {
        if let Some(f) = self.get_memory(id) {
            return Some((f, Hit::Memory));
        }
        let disk = self.disk.as_ref()?;
        let path = disk.path(id)?;
        let (finished, size) = match read_entry(&path, id) {
            Ok(Some((f, size))) => (Arc::new(f), size),
            Ok(None) => {
                // Deleted behind the index's back (evicted meanwhile, or by another server).
                disk.files.invalidate(id);
                return None;
            }
            Err(Unreadable::Corrupt(why)) => {
                tracing::warn!(id, %why, "discarding corrupt cache file");
                let _ = std::fs::remove_file(&path);
                disk.files.invalidate(id);
                return None;
            }
            // The directory itself is unusable (gone, replaced, unreadable): the file may be
            // fine, and results are still kept in memory.
            Err(Unreadable::Io(e)) => {
                tracing::warn!(id, error = %e, "could not read cache file");
                return None;
            }
        };
        // Marks it used, or indexes a file another process sharing the directory wrote.
        if disk.files.get(id).is_none() {
            disk.add(id, size);
        }
        self.memory.insert(id.to_owned(), finished.clone());
        Some((finished, Hit::Disk))
    }

    /// Whether a disk mirror is configured (lookups may then block).
    pub fn has_disk(&self) -> bool {
        self.disk.is_some()
    }

    /// Stores an entry in memory and, if configured, on disk (blocking). A mesh whose file
    /// would not fit in the directory's whole limit stays in memory only.
    pub fn insert(&self, id: &str, finished: Arc<RunResult>) {
        if let Some(disk) = &self.disk
            && let Some(path) = disk.path(id)
        {
            match write_entry(&path, id, &finished, disk.limit) {
                Ok(Some(size)) => disk.add(id, size),
                Ok(None) => tracing::debug!(id, "mesh larger than the cache directory's limit: not written"),
                Err(e) => tracing::warn!(id, error = %e, "could not write cache file"),
            }
        }
        self.memory.insert(id.to_owned(), finished);
    }

    /// Keeps the result of a run a time limit stopped, in memory only, apart from the answers.
    pub fn insert_partial(&self, id: &str, result: Arc<RunResult>) {
        self.partial.insert(id.to_owned(), result);
    }

    /// The result of a run of `id` that a time limit stopped, if still held.
    pub fn get_partial(&self, id: &str) -> Option<Arc<RunResult>> {
        self.partial.get(id)
    }

    /// Bytes of results held in memory as last counted, without applying pending
    /// insertions and evictions: cheap enough for every admission.
    pub fn memory_bytes_estimate(&self) -> u64 {
        self.memory.weighted_size() + self.partial.weighted_size()
    }

    /// Bytes of results held in memory.
    pub fn memory_bytes(&self) -> u64 {
        self.memory.run_pending_tasks();
        self.partial.run_pending_tasks();
        self.memory.weighted_size() + self.partial.weighted_size()
    }

    /// Bytes of the mesh files this server has indexed in the cache directory (0 without
    /// one). Current as of the last write: it runs no maintenance, so async callers never wait.
    pub fn disk_bytes(&self) -> u64 {
        self.disk.as_ref().map_or(0, |disk| disk.files.weighted_size())
    }
}

impl Disk {
    /// Indexes the files an earlier run left in `dir`, oldest first so that they leave first,
    /// and deletes the oldest of them beyond `limit` bytes. Also sweeps temporary files a crash
    /// left behind (those more than an hour old: a younger one may be another server's write).
    fn open(dir: PathBuf, limit: u64) -> std::io::Result<Self> {
        std::fs::create_dir_all(&dir)?;
        // A directory we cannot write to would fail every store, silently: find out now.
        let probe = dir.join(format!(".probe-{}.tmp", std::process::id()));
        std::fs::write(&probe, b"meshfit").and_then(|()| std::fs::remove_file(&probe))?;
        let evicted = Arc::new(std::sync::Mutex::new(Vec::new()));
        let files = moka::sync::Cache::builder()
            .max_capacity(limit)
            .weigher(|_: &String, size: &u64| u32::try_from(*size).unwrap_or(u32::MAX))
            // Plain LRU, the mesh unused for longest first: TinyLFU's admission filter could
            // turn away the file just written.
            .eviction_policy(EvictionPolicy::lru())
            .eviction_listener({
                let evicted = evicted.clone();
                move |id: Arc<String>, _, cause| {
                    if cause == RemovalCause::Size {
                        evicted.lock().unwrap_or_else(|e| e.into_inner()).push(id.to_string());
                    }
                }
            })
            .build();
        let disk = Self { dir, limit, files, evicted };
        let an_hour_ago = SystemTime::now() - std::time::Duration::from_secs(3600);
        let mut found = Vec::new();
        for entry in std::fs::read_dir(&disk.dir)?.filter_map(Result::ok) {
            let (Some(name), Ok(meta)) = (entry.file_name().to_str().map(str::to_owned), entry.metadata())
            else {
                continue;
            };
            let modified = meta.modified().unwrap_or(SystemTime::UNIX_EPOCH);
            if let Some(id) = name.strip_suffix(".mesh").filter(|id| disk.path(id).is_some()) {
                found.push((modified, id.to_owned(), meta.len()));
            } else if name.ends_with(".tmp") && modified < an_hour_ago {
                let _ = std::fs::remove_file(entry.path());
            }
        }
        found.sort();
        for (_, id, size) in found {
            disk.files.insert(id, size);
        }
        disk.evict();
        Ok(disk)
    }

    /// Indexes file `id` of `size` bytes as just used, deleting the least recently used files
    /// if that passes the limit.
    fn add(&self, id: &str, size: u64) {
        self.files.insert(id.to_owned(), size);
        self.evict();
    }

    /// Applies the limit now rather than when moka next gets round to it, and deletes the
    /// files the index dropped, unless they have come back since (written again).
    fn evict(&self) {
        self.files.run_pending_tasks();
        let evicted = std::mem::take(&mut *self.evicted.lock().unwrap_or_else(|e| e.into_inner()));
        for id in evicted {
            if !self.files.contains_key(&id) {
                let _ = std::fs::remove_file(self.dir.join(format!("{id}.mesh")));
            }
        }
    }

    fn path(&self, id: &str) -> Option<PathBuf> {
        // Ids are our own hex digests; anything else never names a file.
        crate::spec::is_hex_id(id).then(|| self.dir.join(format!("{id}.mesh")))
    }
}

/// A result's weight in a memory cache: its bytes.
fn weight(_: &String, result: &Arc<RunResult>) -> u32 {
    u32::try_from(result.num_bytes()).unwrap_or(u32::MAX)
}

/// Writes `result` to the file for `id` and returns its size, or `None` (and no file) when
/// it would be larger than `limit`.
fn write_entry(path: &Path, id: &str, result: &RunResult, limit: u64) -> std::io::Result<Option<u64>> {
    // Sized first, so a file over the limit is never written only to be deleted.
    if compact::size(result, id) > limit {
        return Ok(None);
    }
    // Write to a temporary name of our own and rename, so a crash never leaves a half file
    // under the id and two writers (threads or processes sharing the directory) never
    // interleave.
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let unique = format!("{}.{}.tmp", std::process::id(), NEXT.fetch_add(1, Ordering::Relaxed));
    let tmp = path.with_extension(unique);
    let written = (|| {
        let mut file = std::io::BufWriter::new(std::fs::File::create_new(&tmp)?);
        let size = compact::write(result, id, &mut file)?;
        file.flush()?;
        file.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)?;
        Ok(Some(size))
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// The result in the file at `path` and the file's size, `None` if there is no file.
/// Why a cache file was not read.
enum Unreadable {
    /// Reading failed: the file may be fine.
    Io(std::io::Error),
    /// The bytes are not a result of this id.
    Corrupt(String),
}

fn read_entry(path: &Path, id: &str) -> Result<Option<(RunResult, u64)>, Unreadable> {
    let data = match std::fs::read(path) {
        Ok(d) => d,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Unreadable::Io(e)),
    };
    let result = compact::read(&data, id).map_err(|e| Unreadable::Corrupt(e.to_string()))?;
    Ok(Some((result, data.len() as u64)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry() -> Arc<RunResult> {
        static SAMPLE: std::sync::OnceLock<Arc<RunResult>> = std::sync::OnceLock::new();
        SAMPLE
            .get_or_init(|| Arc::new(crate::result::testing::sample(8, crate::refine::Criterion::Error)))
            .clone()
    }

    /// The size of `entry()`'s file.
    fn file_size() -> u64 {
        compact::write(&entry(), &id(1), std::io::sink()).unwrap()
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
        Cache::new(1 << 20, Some(dir.clone()), 1 << 20).unwrap().insert(ID, entry());
        let (got, hit) = Cache::new(1 << 20, Some(dir.clone()), 1 << 20).unwrap().get(ID).unwrap();
        assert_eq!((got, hit), (entry(), Hit::Disk));
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_corrupt_file_is_deleted_and_reported_as_a_miss() {
        let dir = temp_dir("corrupt");
        Cache::new(1 << 20, Some(dir.clone()), 1 << 20).unwrap().insert(ID, entry());
        let path = dir.join(format!("{ID}.mesh"));
        let mut data = std::fs::read(&path).unwrap();
        *data.last_mut().unwrap() ^= 1;
        std::fs::write(&path, data).unwrap();
        assert_eq!(Cache::new(1 << 20, Some(dir.clone()), 1 << 20).unwrap().get(ID), None);
        assert!(!path.exists(), "the corrupt file should be gone");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn ids_that_are_not_our_digests_never_touch_the_disk() {
        let dir = temp_dir("ids");
        let cache = Cache::new(1 << 20, Some(dir.clone()), 1 << 20).unwrap();
        assert_eq!(cache.disk.as_ref().unwrap().path("../../etc/passwd"), None);
        std::fs::remove_dir_all(dir).unwrap();
    }

    fn id(k: u8) -> String {
        format!("{k:064x}")
    }

    fn files(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        names.sort();
        names
    }

    #[test]
    fn the_directory_keeps_within_its_limit_dropping_the_least_recently_used_file() {
        let dir = temp_dir("limit");
        let size = file_size();
        // Room for three files; no memory cache (capacity 0 turns moka off), so reads go to disk.
        let cache = Cache::new(0, Some(dir.clone()), 3 * size).unwrap();
        for k in 1..=3 {
            cache.insert(&id(k), entry());
        }
        assert_eq!(cache.get(&id(1)).map(|(_, hit)| hit), Some(Hit::Disk));
        cache.insert(&id(4), entry());
        // 2 was used least recently: 1 was read after it.
        assert_eq!(files(&dir), [1, 3, 4].map(|k| format!("{}.mesh", id(k))));
        assert_eq!(cache.disk_bytes(), 3 * size);
        assert!(cache.get(&id(2)).is_none());
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_mesh_served_from_memory_keeps_its_file() {
        let dir = temp_dir("memory-hit");
        let size = file_size();
        let cache = Cache::new(1 << 20, Some(dir.clone()), 3 * size).unwrap();
        for k in 1..=3 {
            cache.insert(&id(k), entry());
        }
        assert!(cache.get_memory(&id(1)).is_some());
        cache.insert(&id(4), entry());
        assert_eq!(files(&dir), [1, 3, 4].map(|k| format!("{}.mesh", id(k))));
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_mesh_larger_than_the_limit_stays_in_memory_only() {
        let dir = temp_dir("too-big");
        let size = file_size();
        let cache = Cache::new(1 << 20, Some(dir.clone()), size - 1).unwrap();
        cache.insert(&id(1), entry());
        assert!(files(&dir).is_empty());
        assert_eq!(cache.get(&id(1)).map(|(_, hit)| hit), Some(Hit::Memory));
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_restart_with_a_smaller_limit_deletes_the_oldest_files() {
        let dir = temp_dir("restart");
        let cache = Cache::new(1 << 20, Some(dir.clone()), 1 << 20).unwrap();
        for k in 1..=4 {
            cache.insert(&id(k), entry());
        }
        // Written in the order 3, 1, 4, 2, a second apart.
        let epoch = SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1_700_000_000);
        for (age, k) in [3, 1, 4, 2].into_iter().enumerate() {
            let file =
                std::fs::File::options().write(true).open(dir.join(format!("{}.mesh", id(k)))).unwrap();
            file.set_modified(epoch + std::time::Duration::from_secs(age as u64)).unwrap();
        }
        // A crash's leftover, and another server's write in progress.
        std::fs::File::create(dir.join("old.1.tmp")).unwrap().set_modified(epoch).unwrap();
        std::fs::File::create(dir.join("new.2.tmp")).unwrap();
        let size = cache.disk_bytes() / 4;
        let reopened = Cache::new(1 << 20, Some(dir.clone()), 2 * size).unwrap();
        let mut expected = vec!["new.2.tmp".to_owned()];
        expected.extend([2, 4].map(|k| format!("{}.mesh", id(k))));
        expected.sort();
        assert_eq!(files(&dir), expected);
        assert_eq!(reopened.get(&id(4)).map(|(_, hit)| hit), Some(Hit::Disk));
        std::fs::remove_dir_all(dir).unwrap();
    }
}
