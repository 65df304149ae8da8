//! Where things live in Redis: the keys, the channels, and the scripts that change a job's
//! keys at once.

use crate::jobs::peers::Kept;

pub(super) const EVENTS: &str = "meshfit:events";
pub(super) const CONTROL: &str = "meshfit:control";
pub(super) const PENDING: &str = "meshfit:pending";
pub(super) const DROPPED: &str = "meshfit:dropped";

pub(super) fn key(kind: &str, id: &str) -> String {
    format!("meshfit:{kind}:{id}")
}

pub(super) fn result_key(kept: Kept, id: &str) -> String {
    match kept {
        Kept::Whole => key("result", id),
        Kept::Partial => key("partial", id),
    }
}

/// A script, hashed once: redis-rs sends its SHA-1 (EVALSHA) and the body only when Redis
/// does not know it yet.
pub(super) type Lua = std::sync::LazyLock<redis::Script>;

/// Takes a lease nobody holds for token ARGV[1] and, for a fresh submission (ARGV[3] = 1),
/// drops the posting of an earlier run and what was asked of it; else answers the holder's
/// token.
pub(super) static ACQUIRE: Lua = Lua::new(|| {
    redis::Script::new(
        r"local held = redis.call('get', KEYS[1])
if held then return held end
redis.call('set', KEYS[1], ARGV[1], 'PX', ARGV[2])
if ARGV[3] == '1' then redis.call('del', KEYS[2], KEYS[3], KEYS[4]) end
return false",
    )
});

/// Extends a lease if this run holds it.
pub(super) static RENEW: Lua = Lua::new(|| {
    redis::Script::new(
        r"if redis.call('get', KEYS[1]) == ARGV[1] then
  return redis.call('pexpire', KEYS[1], ARGV[2]) else return 0 end",
    )
});

/// Deletes a lease if this run holds it.
pub(super) static RELEASE: Lua = Lua::new(|| {
    redis::Script::new(
        r"if redis.call('get', KEYS[1]) == ARGV[1] then
  return redis.call('del', KEYS[1]) else return 0 end",
    )
});

/// Stores and publishes a posting if run ARGV[1] holds the lease, or, with ARGV[1] empty, if
/// no run does.
pub(super) static POST: Lua = Lua::new(|| {
    redis::Script::new(
        r"if (redis.call('get', KEYS[2]) or '') ~= ARGV[1] then return 0 end
redis.call('set', KEYS[1], ARGV[2], 'PX', ARGV[3])
redis.call('publish', ARGV[4], ARGV[5])
return 1",
    )
});

/// Appends ARGV[3..] to list KEYS[1] if it holds ARGV[1] entries, and keeps it ARGV[2] ms;
/// else answers the entries from ARGV[1] on (a list of lists, so that no entry count meets
/// Lua's stack).
pub(super) static APPEND_LOG: Lua = Lua::new(|| {
    redis::Script::new(
        r"if redis.call('llen', KEYS[1]) ~= tonumber(ARGV[1]) then
  return {0, redis.call('lrange', KEYS[1], ARGV[1], -1)}
end
for i = 3, #ARGV do redis.call('rpush', KEYS[1], ARGV[i]) end
redis.call('pexpire', KEYS[1], ARGV[2])
return {1, {}}",
    )
});
