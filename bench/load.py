#!/usr/bin/env python3
"""Load and abuse: throughput, a liveness probe under load, bursts, idle and slow clients,
stalled readers and large uploads, each against a fresh server. Run by hand, never in CI.

    python3 bench/load.py                        # builds target/release/meshfit, all scenarios
    python3 bench/load.py --quick                # every scenario shortened: about 3 minutes
    python3 bench/load.py --binary /path/to/meshfit --scenario burst idle_slow --out load.md
    python3 bench/load.py --set MESHFIT_QUEUE=32 # an extra setting for every scenario

Python 3.11 standard library only, plus `wrk` for the throughput scenario (`cached`):
`apt-get install wrk` (Debian/Ubuntu) or `brew install wrk`. Without `--binary` it runs
`cargo build --release --locked` and uses $CARGO_TARGET_DIR/release/meshfit (default
target/), so the same script measures a baseline build (`--binary`) and the new one.

Every scenario starts its own server on a free loopback port, with only the MESHFIT_*
variables below in its environment (inherited ones are dropped: the server rejects unknown
settings), its stdout and stderr in a log file, and a file-descriptor limit of 1024 (soft and
hard, set in the child before exec). The client raises its own limit to the hard limit. After
the scenario the server gets SIGTERM (SIGKILL if it has not exited 20 s later).

Settings of every scenario (then each scenario's own, then --set):
    MESHFIT_WORKERS=2              two refinements at once, whatever the machine
    MESHFIT_SHUTDOWN_GRACE_MS=2000 so SIGTERM does not wait 10 s for the long jobs
    MESHFIT_LOG=warn               no line per request (wrk would measure the logger);
                                   errors such as failed accepts are still logged
    MESHFIT_LOG_FORMAT=text

Measured for every scenario, beside what the scenario itself counts:
  * peak RSS of the server: VmRSS from /proc/PID/status every 50 ms, and VmHWM at the end
    (before SIGTERM); the larger is reported. The server's open descriptors (/proc/PID/fd)
    are sampled every 250 ms and the peak is in the notes.
  * a /healthz probe: from a process of its own (so the client's load does not delay
    it), GET /healthz on a NEW connection every 100 ms, each with a 5 s timeout, started
    on schedule whether or not earlier probes have answered; p50/p99/max of the answered
    ones, and failures (errors, non-200 answers and timeouts, timeouts also counted apart).
  * the server log: lines naming "Too many open files", panics and ERROR/WARN lines are
    counted in the notes; the logs stay in the directory printed at the end.

Scenarios (durations: full / --quick):
  cached              POST /v1/meshes {"function": "sin(5*x)*y", "max_vertices": 2000} once
                      (the second one must be x-cache: hit), then wrk -t2 -c200 --latency
                      --timeout 5s for 10 s / 5 s POSTing the same body (a Lua script in a
                      temporary file), all answered from the cache. Requests, req/s, p50 and
                      p99 are wrk's; status codes are counted by the Lua script; connection
                      errors are wrk's connect + read + write errors and timeouts.
                      Own settings: MESHFIT_QUEUE=64.
  healthz_under_jobs  POST /v1/jobs with 12 / 8 distinct long jobs ("sin(30*x)*cos(30*y)+k",
                      max_vertices 1000000), which keeps both workers busy for longer than
                      the scenario, then the probe runs for 15 s / 8 s. The row's requests,
                      req/s, latencies and codes are the probe's; the notes say how the
                      submissions were answered and how many jobs were running at the end.
                      Own settings: MESHFIT_QUEUE=64.
  burst               200 connections are opened, then 200 distinct POST /v1/jobs
                      ("sin(12*x)*cos(12*y)+k", max_vertices 200000) are sent on them at
                      once (30 s timeout each). Counts 200/201/202 against 503/429 refusals,
                      refusals without Retry-After, and the distinct Retry-After values;
                      then GET /readyz, and 5 s / 3 s more of the probe with the queue full.
                      Own settings: MESHFIT_QUEUE=16.
  idle_slow           1,000 idle connections (connect, send nothing), 200 that send half a
                      request header and stall, 200 that send a full POST /v1/meshes header
                      with Content-Length 1000000 and then 10 bytes of body a second; opened
                      interleaved (5 idle, 1 half, 1 slow, ...), 200 connects at a time, 5 s
                      connect timeout. Held 60 s / 30 s; every 5 s a non-blocking recv on each
                      (b'' or an error: the server closed it; any bytes the server sent are
                      read, and their status line counted). Reports when each group was
                      closed, or "open at end". Requests = connections attempted; codes =
                      answers the server sent on them; connection errors = failed connects.
                      Default server settings otherwise (MESHFIT_QUEUE=64).
  stalled_sse         POST /v1/meshes {"function": "x*x+y*y", "max_vertices": 1000000,
                      "method": "recursive", "criterion": "variation"} once, read whole (the
                      id is its ETag), then 20 connections GET /v1/jobs/{id}/events with
                      Accept: text/event-stream and 20 GET /v1/jobs/{id}/mesh, each with
                      SO_RCVBUF 4096 set before connecting, and never read (the status line is
                      only peeked). Held 30 s / 15 s; every 5 s the server side of each
                      connection is looked up in /proc/net/tcp (ESTABLISHED: open; any other
                      state or gone: the server closed it), with the bytes queued in the
                      kernel towards the stalled clients. Own settings: MESHFIT_QUEUE=64,
                      MESHFIT_CACHE_BYTES=1073741824.
  uploads             5 / 2 rounds of 8 concurrent POST /v1/meshes (so that the probe's
                      p99 rests on 150 or more probes), content-type application/json, each a
                      256 MiB body streamed from one reused 1 MiB chunk: a grid of 4097 x 4097
                      whose "values" are 19-byte numbers, then an unknown top-level field at
                      its very end, so the whole body is read and the answer is a 422. 300 s
                      timeout. Reports status codes and the problem type, the upload rate and
                      peak RSS. Own settings: MESHFIT_MAX_BODY_BYTES=268435456.

At the end a Markdown table of all rows (and the notes under it) is printed, and written to
--out FILE when given. A scenario that goes over its time budget is cut short and says so.
"""

import argparse
import asyncio
import atexit
import json
import math
import os
import re
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HOST = "127.0.0.1"
SERVER_FD_LIMIT = 1024
MiB = 1 << 20

BASE_SETTINGS = {
    "MESHFIT_WORKERS": "2",
    "MESHFIT_SHUTDOWN_GRACE_MS": "2000",
    "MESHFIT_LOG": "warn",
    "MESHFIT_LOG_FORMAT": "text",
}

REFUSALS = (429, 503)


# ------------------------------------------------------------------------------------------
# Small helpers


def percentile(values, p):
    """The p-th percentile (nearest rank) of values, None when empty."""
    if not values:
        return None
    s = sorted(values)
    return s[max(0, min(len(s) - 1, math.ceil(p / 100 * len(s)) - 1))]


def fmt_ms(v):
    if v is None:
        return "-"
    return f"{v:.2f}" if v < 10 else f"{v:.1f}" if v < 1000 else f"{v:.0f}"


def fmt_rate(v):
    if v is None:
        return "-"
    return f"{v:.2f}" if v < 10 else f"{v:.0f}"


def fmt_codes(codes):
    return " ".join(f"{k}:{v}" for k, v in sorted(codes.items(), key=lambda kv: str(kv[0]))) or "-"


def free_port():
    with socket.socket() as s:
        s.bind((HOST, 0))
        return s.getsockname()[1]


def raise_own_fd_limit():
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = hard if hard != resource.RLIM_INFINITY else 1 << 20
    try:
        resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
    except (ValueError, OSError):
        target = soft
    return target


def limit_server_fds():
    """preexec_fn of the server: 1024 descriptors, soft and hard."""
    resource.setrlimit(resource.RLIMIT_NOFILE, (SERVER_FD_LIMIT, SERVER_FD_LIMIT))


TCP_STATES = {1: "ESTABLISHED", 2: "SYN_SENT", 3: "SYN_RECV", 4: "FIN_WAIT1", 5: "FIN_WAIT2",
              6: "TIME_WAIT", 7: "CLOSE", 8: "CLOSE_WAIT", 9: "LAST_ACK", 10: "LISTEN", 11: "CLOSING"}


def tcp_table():
    """(local port, remote port, state, tx queue bytes) of every TCP socket in this namespace."""
    rows = []
    for path in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(path) as f:
                lines = f.read().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            p = line.split()
            try:
                rows.append((int(p[1].rsplit(":", 1)[1], 16), int(p[2].rsplit(":", 1)[1], 16), int(p[3], 16),
                             int(p[4].split(":")[0], 16)))
            except (IndexError, ValueError):
                pass
    return rows


# ------------------------------------------------------------------------------------------
# A minimal HTTP/1.1 client on asyncio streams


@dataclass
class Response:
    status: int
    headers: dict
    body: bytes
    length: int
    elapsed: float


async def read_head(reader):
    raw = await reader.readuntil(b"\r\n\r\n")
    lines = raw.decode("latin-1").split("\r\n")
    parts = lines[0].split(" ", 2)
    if len(parts) < 2 or not parts[0].startswith("HTTP/"):
        raise ValueError(f"bad status line {lines[0]!r}")
    headers = {}
    for line in lines[1:]:
        if ":" in line:
            k, v = line.split(":", 1)
            headers[k.strip().lower()] = v.strip()
    return int(parts[1]), headers


async def read_body(reader, headers, keep):
    """The body, keeping at most `keep` bytes of it; returns (kept bytes, total length)."""
    kept, total = bytearray(), 0

    def take(data):
        nonlocal total
        total += len(data)
        if len(kept) < keep:
            kept.extend(data[: keep - len(kept)])

    if "chunked" in headers.get("transfer-encoding", "").lower():
        while True:
            size = int((await reader.readuntil(b"\r\n")).split(b";")[0].strip() or b"0", 16)
            if size == 0:
                while (await reader.readuntil(b"\r\n")) != b"\r\n":
                    pass
                break
            while size > 0:
                data = await reader.read(min(size, MiB))
                if not data:
                    raise asyncio.IncompleteReadError(b"", size)
                take(data)
                size -= len(data)
            await reader.readexactly(2)
    elif "content-length" in headers:
        left = int(headers["content-length"])
        while left > 0:
            data = await reader.read(min(left, MiB))
            if not data:
                raise asyncio.IncompleteReadError(b"", left)
            take(data)
            left -= len(data)
    else:
        while data := await reader.read(MiB):
            take(data)
    return bytes(kept), total


async def request(port, method, path, body=b"", headers=None, timeout=30.0, keep=1 << 16):
    """One request on a new connection (Connection: close), bounded by `timeout` in all."""
    start = time.perf_counter()

    async def go():
        reader, writer = await asyncio.open_connection(HOST, port, limit=1 << 20)
        try:
            h = {"Host": f"{HOST}:{port}", "Connection": "close"}
            if body or method in ("POST", "PUT"):
                h["Content-Length"] = str(len(body))
            h.update(headers or {})
            head = f"{method} {path} HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in h.items()) + "\r\n"
            writer.write(head.encode("latin-1") + body)
            await writer.drain()
            status, rh = await read_head(reader)
            kept, total = await read_body(reader, rh, keep)
            return Response(status, rh, kept, total, time.perf_counter() - start)
        finally:
            writer.transport.abort()

    return await asyncio.wait_for(go(), timeout)


def post_json(port, path, doc, timeout=30.0, **kw):
    return request(port, "POST", path, json.dumps(doc).encode(), {"Content-Type": "application/json"},
                   timeout=timeout, **kw)


# ------------------------------------------------------------------------------------------
# The server, its memory, and the liveness probe

LIVE_SERVERS = set()


class Server:
    def __init__(self, binary, settings, logdir, name):
        self.binary, self.settings, self.name = binary, settings, name
        self.log_path = Path(logdir) / f"{name}.log"
        self.proc = None
        self.port = None
        self.stop_note = ""

    def start(self):
        self.port = free_port()
        env = {k: v for k, v in os.environ.items() if not k.startswith("MESHFIT_")}
        env.update(self.settings)
        env["MESHFIT_ADDR"] = f"{HOST}:{self.port}"
        with open(self.log_path, "wb") as log:
            self.proc = subprocess.Popen([str(self.binary)], env=env, stdin=subprocess.DEVNULL, stdout=log,
                                         stderr=subprocess.STDOUT, preexec_fn=limit_server_fds,
                                         start_new_session=True)
        LIVE_SERVERS.add(self)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"the server exited with {self.proc.returncode} at start:\n{self.log_tail()}")
            try:
                with socket.create_connection((HOST, self.port), timeout=1) as s:
                    s.settimeout(2)
                    s.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
                    if s.recv(64).startswith(b"HTTP/1.1 200"):
                        return
            except OSError:
                pass
            time.sleep(0.05)
        self.stop()
        raise RuntimeError(f"the server did not answer /healthz within 30 s:\n{self.log_tail()}")

    def log_tail(self, n=20):
        try:
            return "\n".join(self.log_path.read_text(errors="replace").splitlines()[-n:])
        except OSError:
            return ""

    def stop(self):
        """SIGTERM, then SIGKILL after 20 s; notes how it went."""
        if self.proc is None or self.proc.poll() is not None:
            LIVE_SERVERS.discard(self)
            return
        start = time.monotonic()
        try:
            self.proc.send_signal(signal.SIGTERM)
            self.proc.wait(timeout=20)
            took = time.monotonic() - start
            self.stop_note = f"exit {self.proc.returncode} {took:.1f} s after SIGTERM"
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            self.stop_note = "still running 20 s after SIGTERM: killed"
        finally:
            LIVE_SERVERS.discard(self)

    def kill(self):
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass


@atexit.register
def _kill_leftovers():
    for s in list(LIVE_SERVERS):
        s.kill()


class ProcMonitor(threading.Thread):
    """VmRSS every 50 ms and the open descriptors every 250 ms of one process."""

    def __init__(self, pid):
        super().__init__(daemon=True)
        self.pid = pid
        self.peak_kb = 0
        self.peak_fds = 0
        self.halt = threading.Event()

    def status_kb(self, key):
        try:
            with open(f"/proc/{self.pid}/status") as f:
                for line in f:
                    if line.startswith(key + ":"):
                        return int(line.split()[1])
        except (OSError, ValueError, IndexError):
            pass
        return 0

    def rss_mib(self):
        return self.status_kb("VmRSS") / 1024

    def run(self):
        i = 0
        while not self.halt.is_set():
            self.peak_kb = max(self.peak_kb, self.status_kb("VmRSS"))
            if i % 5 == 0:
                try:
                    self.peak_fds = max(self.peak_fds, len(os.listdir(f"/proc/{self.pid}/fd")))
                except OSError:
                    pass
            i += 1
            self.halt.wait(0.05)

    def finish(self):
        """The peak in MiB: the polled maximum or VmHWM, whichever is larger."""
        hwm = self.status_kb("VmHWM")
        self.halt.set()
        self.join(5)
        return max(self.peak_kb, hwm) / 1024


class Probe(threading.Thread):
    """GET /healthz on a new connection every 100 ms, 5 s timeout each, in its own loop.

    Runs inside the probe process (`--probe-child PORT`); `records` holds one
    (wall-clock start, outcome, latency ms) per probe, the outcome a status code, "timeout"
    or the name of the error."""

    def __init__(self, port, interval=0.1, timeout=5.0):
        super().__init__(daemon=True)
        self.port, self.interval, self.timeout = port, interval, timeout
        self.records = []
        self.halt = threading.Event()

    def run(self):
        asyncio.run(self.main())

    async def one(self):
        wall, start = time.time(), time.perf_counter()
        try:
            r = await request(self.port, "GET", "/healthz", timeout=self.timeout)
            outcome = r.status
        except asyncio.TimeoutError:
            outcome = "timeout"
        except Exception as e:  # noqa: BLE001 - every failure counts, whatever it is
            outcome = type(e).__name__
        self.records.append((wall, outcome, (time.perf_counter() - start) * 1e3))

    async def main(self):
        loop = asyncio.get_running_loop()
        tasks = set()
        tick = loop.time()
        while not self.halt.is_set():
            t = asyncio.create_task(self.one())
            tasks.add(t)
            t.add_done_callback(tasks.discard)
            tick += self.interval
            await asyncio.sleep(max(0.0, tick - loop.time()))
        if tasks:
            _, pending = await asyncio.wait(tasks, timeout=self.timeout + 1)
            for t in pending:
                t.cancel()

    def stop(self):
        self.halt.set()
        self.join(self.timeout + 5)


def probe_child(port):
    """The probe process: probes until its stdin closes, then prints its records as JSON."""
    probe = Probe(port)
    probe.start()
    try:
        sys.stdin.buffer.read()
    except KeyboardInterrupt:
        pass
    probe.stop()
    json.dump(list(probe.records), sys.stdout)


@dataclass
class ProbeStats:
    sent: int
    latencies: list  # of the 200 answers, ms
    failures: int
    timeouts: int
    outcomes: Counter

    def p(self, q):
        return percentile(self.latencies, q)

    def failures_cell(self):
        return f"{self.failures}" + (f" ({self.timeouts} timeouts)" if self.timeouts else "")


class ProbeProcess:
    """The /healthz probe in a process of its own, so the client's own load (one GIL) does
    not delay it."""

    def __init__(self, port):
        self.port = port
        self.proc = None
        self.records = []

    def start(self):
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--probe-child",
                                      str(self.port)], stdin=subprocess.PIPE, stdout=subprocess.PIPE)

    def stop(self):
        if self.proc is None:
            return
        try:
            out, _ = self.proc.communicate(input=b"", timeout=20)
            self.records = json.loads(out or b"[]")
        except (subprocess.TimeoutExpired, ValueError):
            self.proc.kill()
            self.proc.wait()
        self.proc = None

    def stats(self, since=None, until=None):
        """Of the probes started in [since, until] (wall clock), or all."""
        recs = [r for r in self.records if (since is None or r[0] >= since) and (until is None or r[0] <= until)]
        ok = [lat for _, outcome, lat in recs if outcome == 200]
        return ProbeStats(len(recs), ok, len(recs) - len(ok), sum(o == "timeout" for _, o, _ in recs),
                          Counter(o for _, o, _ in recs))


# ------------------------------------------------------------------------------------------
# Rows


@dataclass
class Row:
    scenario: str
    sent: int = 0
    rps: float = None
    p50: float = None
    p99: float = None
    codes: Counter = field(default_factory=Counter)
    refusals: int = 0
    conn_errors: int = 0
    rss_mib: float = None
    hz_p99: float = None
    hz_failures: str = "-"
    notes: list = field(default_factory=list)
    probe_window: tuple = None

    def cells(self):
        return [self.scenario, str(self.sent), fmt_rate(self.rps), fmt_ms(self.p50), fmt_ms(self.p99),
                fmt_codes(self.codes), str(self.refusals), str(self.conn_errors),
                "-" if self.rss_mib is None else f"{self.rss_mib:.0f}", fmt_ms(self.hz_p99), self.hz_failures]


HEADER = ["scenario", "requests", "req/s", "p50 ms", "p99 ms", "status codes", "refusals", "conn errors",
          "peak RSS MiB", "healthz p99 ms", "healthz failures"]


def md_row(cells):
    return "| " + " | ".join(cells) + " |"


def md_table(rows):
    lines = [md_row(HEADER), md_row(["---"] * len(HEADER))]
    lines += [md_row(r.cells()) for r in rows]
    notes = [f"- **{r.scenario}**: " + "; ".join(r.notes) for r in rows if r.notes]
    return "\n".join(lines) + ("\n\n" + "\n".join(notes) if notes else "") + "\n"


# ------------------------------------------------------------------------------------------
# Scenarios. Each takes (ctx, server, row, monitor) and fills the row.


@dataclass
class Ctx:
    quick: bool
    wrk: str
    tmp: Path


WRK_LUA = r"""
wrk.method = "POST"
wrk.body = [==[%s]==]
wrk.headers["Content-Type"] = "application/json"
local threads = {}
function setup(thread) table.insert(threads, thread) end
function init(args) codes = {} end
function response(status, headers, body) codes[status] = (codes[status] or 0) + 1 end
function done(summary, latency, requests)
  local total = {}
  for _, t in ipairs(threads) do
    for k, v in pairs(t:get("codes")) do total[k] = (total[k] or 0) + v end
  end
  for k, v in pairs(total) do io.write(string.format("STATUS %%d %%d\n", k, v)) end
  local e = summary.errors
  io.write(string.format("SUMMARY %%d %%d %%d %%d %%d %%d %%d\n", summary.requests, summary.duration,
    e.connect, e.read, e.write, e.status, e.timeout))
  for _, p in ipairs({50, 99}) do io.write(string.format("LAT %%d %%d\n", p, latency:percentile(p))) end
end
"""


async def scenario_cached(ctx, server, row, monitor):
    body = {"function": "sin(5*x)*y", "max_vertices": 2000}
    first = await post_json(server.port, "/v1/meshes", body, timeout=60)
    second = await post_json(server.port, "/v1/meshes", body, timeout=60)
    row.notes.append(f"warm-up {first.status} in {first.elapsed * 1e3:.0f} ms, then {second.status} "
                     f"x-cache: {second.headers.get('x-cache', '?')} ({second.length} bytes)")
    if first.status != 200:
        raise RuntimeError(f"warm-up answered {first.status}: {first.body[:300]!r}")
    lua = ctx.tmp / "cached.lua"
    lua.write_text(WRK_LUA % json.dumps(body))
    duration = 5 if ctx.quick else 10
    cmd = [ctx.wrk, "-t2", "-c200", f"-d{duration}s", "--latency", "--timeout", "5s", "-s", str(lua),
           f"http://{HOST}:{server.port}/v1/meshes"]
    proc = await asyncio.create_subprocess_exec(*cmd, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.PIPE)
    try:
        out, err = await asyncio.wait_for(proc.communicate(), duration + 30)
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
    text = out.decode(errors="replace")
    if proc.returncode != 0 or "SUMMARY" not in text:
        raise RuntimeError(f"wrk failed ({proc.returncode}): {err.decode(errors='replace')[-500:]} {text[-500:]}")
    for line in text.splitlines():
        p = line.split()
        if line.startswith("STATUS "):
            row.codes[int(p[1])] += int(p[2])
        elif line.startswith("SUMMARY "):
            requests, _, connect, read, write, status, timeout = map(int, p[1:8])
            row.sent = requests
            row.conn_errors = connect + read + write + timeout
            if row.conn_errors:
                row.notes.append(f"wrk socket errors: connect {connect}, read {read}, write {write}, "
                                 f"timeout {timeout}")
        elif line.startswith("LAT 50 "):
            row.p50 = int(p[2]) / 1e3
        elif line.startswith("LAT 99 "):
            row.p99 = int(p[2]) / 1e3
        elif line.startswith("Requests/sec:"):
            row.rps = float(p[1])
    row.refusals = sum(row.codes[c] for c in REFUSALS)


async def scenario_healthz_under_jobs(ctx, server, row, monitor):
    n = 8 if ctx.quick else 12
    duration = 8 if ctx.quick else 15
    ids, submitted = [], Counter()
    for k in range(n):
        doc = {"function": f"sin(30*x)*cos(30*y)+{k}", "max_vertices": 1000000}
        try:
            r = await post_json(server.port, "/v1/jobs", doc, timeout=30)
            submitted[r.status] += 1
            if r.status in (200, 201, 202):
                ids.append(json.loads(r.body)["id"])
        except (OSError, asyncio.TimeoutError, ValueError) as e:
            submitted[type(e).__name__] += 1
    # The row reports the probes started from here on, read after the scenario: row.probe_window.
    started, wall = time.monotonic(), time.time()
    await asyncio.sleep(duration)
    elapsed = time.monotonic() - started
    row.probe_window = (wall, wall + elapsed)
    states = Counter()
    for job in ids:
        try:
            r = await request(server.port, "GET", f"/v1/jobs/{job}", timeout=10)
            states[json.loads(r.body).get("status", r.status) if r.status == 200 else r.status] += 1
        except (OSError, asyncio.TimeoutError, ValueError) as e:
            states[type(e).__name__] += 1
    row.notes.append(f"{n} jobs submitted ({fmt_codes(submitted)}); after {duration} s: {fmt_codes(states)}")
    if states.get("running", 0) < 2:
        row.notes.append("WARNING: fewer than 2 jobs running at the end: the workers were not kept busy")


async def scenario_burst(ctx, server, row, monitor):
    n = 200
    loop = asyncio.get_running_loop()

    async def connect():
        return await asyncio.wait_for(asyncio.open_connection(HOST, server.port, limit=1 << 20), 10)

    conns = await asyncio.gather(*[connect() for _ in range(n)], return_exceptions=True)
    row.conn_errors = sum(isinstance(c, BaseException) for c in conns)
    retry_after, latencies, missing_retry = Counter(), [], 0
    go = asyncio.Event()

    async def one(k, conn):
        nonlocal missing_retry
        reader, writer = conn
        body = json.dumps({"function": f"sin(12*x)*cos(12*y)+{k}", "max_vertices": 200000}).encode()
        head = (f"POST /v1/jobs HTTP/1.1\r\nHost: {HOST}:{server.port}\r\nConnection: close\r\n"
                f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n").encode()
        await go.wait()
        start = loop.time()
        try:
            writer.write(head + body)
            await writer.drain()
            status, headers = await asyncio.wait_for(read_head(reader), 30)
            await asyncio.wait_for(read_body(reader, headers, 0), 30)
            latencies.append((loop.time() - start) * 1e3)
            row.codes[status] += 1
            if status in REFUSALS:
                if "retry-after" in headers:
                    retry_after[headers["retry-after"]] += 1
                else:
                    missing_retry += 1
        except asyncio.TimeoutError:
            row.codes["timeout"] += 1
            row.conn_errors += 1
        except (OSError, asyncio.IncompleteReadError, ValueError, asyncio.LimitOverrunError) as e:
            row.codes[type(e).__name__] += 1
            row.conn_errors += 1
        finally:
            writer.transport.abort()

    tasks = [asyncio.create_task(one(k, c)) for k, c in enumerate(conns) if not isinstance(c, BaseException)]
    try:
        start = loop.time()
        go.set()
        await asyncio.gather(*tasks)
        elapsed = loop.time() - start
    finally:
        for t in tasks:
            t.cancel()
        for c in conns:
            if not isinstance(c, BaseException):
                c[1].transport.abort()
    ready = await request(server.port, "GET", "/readyz", timeout=10)
    await asyncio.sleep(3 if ctx.quick else 5)  # the probe, with the queue full
    row.sent = len(tasks)
    row.rps = row.sent / elapsed if elapsed > 0 else None
    row.p50, row.p99 = percentile(latencies, 50), percentile(latencies, 99)
    row.refusals = sum(row.codes[c] for c in REFUSALS)
    accepted = sum(row.codes[c] for c in (200, 201, 202))
    row.notes.append(f"accepted {accepted}, refused {row.refusals}; Retry-After values: "
                     f"{fmt_codes(retry_after) if retry_after else 'none'}"
                     + (f"; {missing_retry} refusals WITHOUT Retry-After" if missing_retry else "")
                     + f"; /readyz right after: {ready.status}")


async def connect_raw(port, rcvbuf=None, timeout=5.0):
    loop = asyncio.get_running_loop()
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setblocking(False)
    if rcvbuf:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    try:
        await asyncio.wait_for(loop.sock_connect(s, (HOST, port)), timeout)
    except BaseException:
        s.close()
        raise
    return s


async def connect_many(port, count, concurrency=200, **kw):
    """`count` sockets (None where the connect failed), at most `concurrency` connecting at once."""
    gate = asyncio.Semaphore(concurrency)
    failures = Counter()

    async def one():
        async with gate:
            try:
                return await connect_raw(port, **kw)
            except asyncio.TimeoutError:
                failures["timeout"] += 1
            except OSError as e:
                failures[e.strerror or type(e).__name__] += 1
            return None

    return await asyncio.gather(*[one() for _ in range(count)]), failures


class Conn:
    def __init__(self, group, sock):
        self.group, self.sock = group, sock
        self.closed_at = None
        self.received = bytearray()

    def poll(self, now):
        """Non-blocking recv until it would block: b'' or an error means the server closed it."""
        if self.closed_at is not None or self.sock is None:
            return
        try:
            while True:
                data = self.sock.recv(65536)
                if not data:
                    self.closed_at = now
                    return
                if len(self.received) < 4096:
                    self.received.extend(data[:4096])
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self.closed_at = now

    def status(self):
        m = re.match(rb"HTTP/1\.[01] (\d{3})", bytes(self.received))
        return int(m.group(1)) if m else None


async def scenario_idle_slow(ctx, server, row, monitor):
    hold = 30 if ctx.quick else 60
    plan = []  # interleaved: 5 idle, 1 half, 1 slow, 200 times
    for _ in range(200):
        plan += ["idle"] * 5 + ["half", "slow"]
    socks, failures = await connect_many(server.port, len(plan), concurrency=200, timeout=5.0)
    conns = [Conn(g, s) for g, s in zip(plan, socks)]
    row.sent = len(plan)
    row.conn_errors = sum(failures.values())
    groups = {"idle": 1000, "half": 200, "slow": 200}
    try:
        half = (f"POST /v1/meshes HTTP/1.1\r\nHost: {HOST}:{server.port}\r\nContent-Ty").encode()
        full = (f"POST /v1/meshes HTTP/1.1\r\nHost: {HOST}:{server.port}\r\nContent-Type: application/json\r\n"
                f"Content-Length: 1000000\r\n\r\n").encode()
        start = time.monotonic()
        for c in conns:
            if c.sock is None:
                continue
            try:
                if c.group == "half":
                    c.sock.send(half)
                elif c.group == "slow":
                    c.sock.send(full)
            except (BlockingIOError, InterruptedError):
                pass
            except OSError:
                c.closed_at = 0.0
        timeline = []
        for tick in range(1, hold + 1):  # each second 10 bytes of body on each slow connection
            await asyncio.sleep(max(0.0, start + tick - time.monotonic()))
            for c in conns:
                if c.group == "slow" and c.sock is not None and c.closed_at is None:
                    try:
                        c.sock.send(b" " * 10)
                    except (BlockingIOError, InterruptedError):
                        pass
                    except OSError:
                        c.closed_at = tick
            if tick % 5 == 0:
                for c in conns:
                    c.poll(tick)
                timeline.append((tick, Counter(c.group for c in conns if c.sock is not None and
                                               c.closed_at is not None)))
        for c in conns:
            c.poll(hold)
        for c in conns:
            if (s := c.status()) is not None:
                row.codes[s] += 1
        row.refusals = sum(row.codes[c] for c in REFUSALS)
        parts = []
        for g, n in groups.items():
            mine = [c for c in conns if c.group == g]
            connected = sum(c.sock is not None for c in mine)
            closed = sorted(c.closed_at for c in mine if c.sock is not None and c.closed_at is not None)
            if not closed:
                when = "open at end"
            elif len(closed) == connected:
                when = f"all closed by {closed[-1]:.0f} s (first by {closed[0]:.0f} s)"
            else:
                when = f"{len(closed)} closed (first by {closed[0]:.0f} s), {connected - len(closed)} open at end"
            parts.append(f"{g}: {connected}/{n} connected, {when}")
        row.notes.append("; ".join(parts))
        if failures:
            row.notes.append(f"connect failures: {fmt_codes(failures)}")
        row.notes.append("closed by check (idle/half/slow): " +
                         ", ".join(f"{t}s {d['idle']}/{d['half']}/{d['slow']}" for t, d in timeline))
    finally:
        for c in conns:
            if c.sock is not None:
                c.sock.close()


async def scenario_stalled_sse(ctx, server, row, monitor):
    hold = 15 if ctx.quick else 30
    body = {"function": "x*x+y*y", "max_vertices": 1000000, "method": "recursive", "criterion": "variation"}
    r = await post_json(server.port, "/v1/meshes", body, timeout=180, keep=256)
    etag = r.headers.get("etag", "").strip('"')
    m = re.search(rb'"id"\s*:\s*"([0-9a-f]{64})"', r.body)
    job = etag or (m.group(1).decode() if m else "")
    if r.status != 200 or not job:
        raise RuntimeError(f"the large mesh answered {r.status}: {r.body[:300]!r}")
    row.notes.append(f"1e6-vertex mesh in {r.elapsed:.1f} s, {r.length / MiB:.0f} MiB of JSON; "
                     f"RSS after it {monitor.rss_mib():.0f} MiB")
    plan = ["events"] * 20 + ["mesh"] * 20
    socks, failures = await connect_many(server.port, len(plan), rcvbuf=4096, timeout=5.0)
    row.sent = len(plan)
    row.conn_errors = sum(failures.values())
    conns = [Conn(g, s) for g, s in zip(plan, socks)]
    try:
        for c in conns:
            if c.sock is None:
                continue
            path, accept = ((f"/v1/jobs/{job}/events", "text/event-stream") if c.group == "events"
                            else (f"/v1/jobs/{job}/mesh", "application/json"))
            try:
                c.sock.send(f"GET {path} HTTP/1.1\r\nHost: {HOST}:{server.port}\r\nAccept: {accept}\r\n\r\n"
                            .encode())
            except OSError:
                c.closed_at = 0.0
        ports = {c.sock.getsockname()[1]: c for c in conns if c.sock is not None}
        start = time.monotonic()
        peeked = False
        timeline, peak_queue, end_states = [], 0, Counter()
        for t in range(5, hold + 1, 5):
            await asyncio.sleep(max(0.0, start + t - time.monotonic()))
            if not peeked:  # the status line only: MSG_PEEK leaves it in the buffer
                for c in ports.values():
                    try:
                        c.received = bytearray(c.sock.recv(16, socket.MSG_PEEK | socket.MSG_DONTWAIT))
                    except OSError:
                        pass
                peeked = True
            server_side = {rport: (st, tx) for lport, rport, st, tx in tcp_table()
                           if lport == server.port and rport in ports}
            queued = sum(tx for _, tx in server_side.values())
            peak_queue = max(peak_queue, queued)
            end_states = Counter(TCP_STATES.get(server_side[p][0], "?") if p in server_side else "gone"
                                 for p in ports)
            for p, c in ports.items():
                st = server_side.get(p, (None, 0))[0]
                if c.closed_at is None and st != 1:
                    c.closed_at = t
            closed = Counter(c.group for c in ports.values() if c.closed_at is not None)
            timeline.append(f"{t}s {closed['events']}/{closed['mesh']}")
        for c in ports.values():
            if (s := c.status()) is not None:
                row.codes[s] += 1
        row.refusals = sum(row.codes[c] for c in REFUSALS)
        parts = []
        for g in ("events", "mesh"):
            mine = [c for c in ports.values() if c.group == g]
            closed = sorted(c.closed_at for c in mine if c.closed_at is not None)
            when = ("open at end" if not closed else
                    f"all closed by {closed[-1]:.0f} s" if len(closed) == len(mine) else
                    f"{len(closed)} closed (first by {closed[0]:.0f} s), {len(mine) - len(closed)} open at end")
            parts.append(f"{g}: {len(mine)}/20 connected, {when}")
        row.notes.append("; ".join(parts))
        row.notes.append(f"closed by check (events/mesh): {', '.join(timeline)}; server side at the end: "
                         f"{fmt_codes(end_states)}; peak kernel send queue towards them {peak_queue / MiB:.1f} MiB")
        if failures:
            row.notes.append(f"connect failures: {fmt_codes(failures)}")
    finally:
        for c in conns:
            if c.sock is not None:
                c.sock.close()


UPLOAD_BYTES = 256 * MiB
UPLOAD_PREFIX = b'{"grid": {"nx": 4097, "ny": 4097, "values": ['
UPLOAD_SUFFIX = b'0]}, "max_vertices": 4, "invalid_at_the_very_end": true}'
UPLOAD_TOKEN = b"0.1234567890123456,"


def upload_pieces(chunk):
    """The body as pieces of one reused chunk: exactly UPLOAD_BYTES, valid JSON but for its end."""
    yield UPLOAD_PREFIX
    left = UPLOAD_BYTES - len(UPLOAD_PREFIX) - len(UPLOAD_SUFFIX)
    while left >= len(chunk):
        yield chunk
        left -= len(chunk)
    tokens = left // len(UPLOAD_TOKEN)
    yield UPLOAD_TOKEN * tokens + b" " * (left - tokens * len(UPLOAD_TOKEN))
    yield UPLOAD_SUFFIX


async def scenario_uploads(ctx, server, row, monitor):
    n, rounds = 8, 2 if ctx.quick else 5
    chunk = UPLOAD_TOKEN * (MiB // len(UPLOAD_TOKEN))
    loop = asyncio.get_running_loop()
    latencies, problems, early = [], Counter(), Counter()

    async def one():
        start = loop.time()
        reader, writer = await asyncio.wait_for(asyncio.open_connection(HOST, server.port, limit=1 << 20), 10)
        try:
            writer.write((f"POST /v1/meshes HTTP/1.1\r\nHost: {HOST}:{server.port}\r\nConnection: close\r\n"
                          f"Content-Type: application/json\r\nContent-Length: {UPLOAD_BYTES}\r\n\r\n").encode())
            sent = 0
            try:
                for piece in upload_pieces(chunk):
                    writer.write(piece)
                    sent += len(piece)
                    await writer.drain()
            except OSError as e:  # the server may answer and close before the end
                early[f"{type(e).__name__} after {sent / MiB:.0f} MiB"] += 1
            status, headers = await read_head(reader)
            kept, _ = await read_body(reader, headers, 4096)
            latencies.append((loop.time() - start) * 1e3)
            row.codes[status] += 1
            try:
                problems[json.loads(kept).get("type", "?")] += 1
            except ValueError:
                pass
        finally:
            writer.transport.abort()

    async def guarded():
        try:
            await asyncio.wait_for(one(), 300)
        except asyncio.TimeoutError:
            row.codes["timeout"] += 1
            row.conn_errors += 1
        except (OSError, asyncio.IncompleteReadError, ValueError, asyncio.LimitOverrunError) as e:
            row.codes[type(e).__name__] += 1
            row.conn_errors += 1

    start = loop.time()
    for _ in range(rounds):
        await asyncio.gather(*[guarded() for _ in range(n)])
    elapsed = loop.time() - start
    row.sent = n * rounds
    row.rps = row.sent / elapsed
    row.p50, row.p99 = percentile(latencies, 50), percentile(latencies, 99)
    row.refusals = sum(row.codes[c] for c in REFUSALS)
    row.notes.append(f"{rounds} x {n} x {UPLOAD_BYTES / MiB:.0f} MiB in {elapsed:.1f} s "
                     f"({row.sent * UPLOAD_BYTES / MiB / elapsed:.0f} MiB/s); problems: {fmt_codes(problems) or '-'}"
                     + (f"; cut short: {fmt_codes(early)}" if early else ""))


SCENARIOS = {
    # name: (function, own settings, time budget in s (full, quick))
    "cached": (scenario_cached, {"MESHFIT_QUEUE": "64"}, (90, 60)),
    "healthz_under_jobs": (scenario_healthz_under_jobs, {"MESHFIT_QUEUE": "64"}, (90, 60)),
    "burst": (scenario_burst, {"MESHFIT_QUEUE": "16"}, (120, 90)),
    "idle_slow": (scenario_idle_slow, {"MESHFIT_QUEUE": "64"}, (150, 100)),
    "stalled_sse": (scenario_stalled_sse, {"MESHFIT_QUEUE": "64", "MESHFIT_CACHE_BYTES": "1073741824"},
                    (300, 240)),
    "uploads": (scenario_uploads, {"MESHFIT_MAX_BODY_BYTES": "268435456"}, (400, 400)),
}


def scan_log(path):
    counts = Counter()
    try:
        with open(path, errors="replace") as f:
            for line in f:
                if "Too many open files" in line:
                    counts["'Too many open files'"] += 1
                if "panicked" in line:
                    counts["panics"] += 1
                if "response failed classification" in line:  # tower-http's line for each 5xx
                    counts["5xx responses logged"] += 1
                elif " ERROR " in line or '"level":"ERROR"' in line:
                    counts["ERROR lines"] += 1
                elif " WARN " in line or '"level":"WARN"' in line:
                    counts["WARN lines"] += 1
    except OSError:
        pass
    return counts


async def run_scenario(name, ctx, binary, extra, logdir):
    fn, own, budgets = SCENARIOS[name]
    settings = {**BASE_SETTINGS, **own, **extra}
    row = Row(name)
    server = Server(binary, settings, logdir, name)
    await asyncio.to_thread(server.start)
    monitor = ProcMonitor(server.proc.pid)
    monitor.start()
    probe = ProbeProcess(server.port)
    probe.start()
    try:
        budget = budgets[1] if ctx.quick else budgets[0]
        await asyncio.wait_for(fn(ctx, server, row, monitor), budget)
    except asyncio.TimeoutError:
        row.notes.append(f"CUT SHORT: over its {budget} s budget")
    except Exception as e:  # noqa: BLE001 - the row says what went wrong, the run goes on
        traceback.print_exc()
        row.notes.append(f"FAILED: {type(e).__name__}: {str(e)[:300]}")
    finally:
        await asyncio.to_thread(probe.stop)
        row.rss_mib = monitor.finish()
        row.notes.append(f"peak server fds {monitor.peak_fds} (limit {SERVER_FD_LIMIT})")
        await asyncio.to_thread(server.stop)
    hz = probe.stats()
    row.hz_p99 = hz.p(99)
    row.hz_failures = hz.failures_cell()
    if row.probe_window:  # the scenario's row is the probe itself, over its window
        w = probe.stats(*row.probe_window)
        row.sent = w.sent
        row.rps = w.sent / (row.probe_window[1] - row.probe_window[0])
        row.p50, row.p99 = w.p(50), w.p(99)
        row.codes = w.outcomes
    others = Counter({k: v for k, v in hz.outcomes.items() if k != 200})
    row.notes.append(f"healthz: {hz.sent} probes, p50 {fmt_ms(hz.p(50))} ms, max "
                     f"{fmt_ms(max(hz.latencies) if hz.latencies else None)} ms"
                     + (f", failed: {fmt_codes(others)}" if others else ""))
    if server.stop_note:
        row.notes.append(server.stop_note)
    if logged := scan_log(server.log_path):
        row.notes.append("server log: " + ", ".join(f"{v} {k}" for k, v in logged.items()))
    return row


def build():
    print("building: cargo build --release --locked", flush=True)
    subprocess.run(["cargo", "build", "--release", "--locked"], cwd=ROOT, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    if not target.is_absolute():
        target = ROOT / target
    return target / "release" / "meshfit"


async def main_async(args, binary, wrk, extra):
    rows = []
    logdir = Path(tempfile.mkdtemp(prefix="meshfit-load-"))
    with tempfile.TemporaryDirectory(prefix="meshfit-load-tmp-") as tmp:
        ctx = Ctx(args.quick, wrk, Path(tmp))
        print(md_row(HEADER), flush=True)
        print(md_row(["---"] * len(HEADER)), flush=True)
        try:
            for name in args.scenario:
                row = await run_scenario(name, ctx, binary, extra, logdir)
                rows.append(row)
                print(md_row(row.cells()), flush=True)
        finally:
            if rows:
                table = md_table(rows)
                print(f"\n## meshfit load ({binary}{', --quick' if args.quick else ''})\n")
                print(table)
                if args.out:
                    Path(args.out).write_text(table)
                    print(f"written to {args.out}")
            print(f"server logs: {logdir}")
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", type=Path, help="a meshfit binary (default: build target/release/meshfit)")
    ap.add_argument("--scenario", nargs="+", action="extend", choices=list(SCENARIOS),
                    help="scenarios to run, in this order (default: all)")
    ap.add_argument("--quick", action="store_true", help="shorten every scenario (about 3 minutes in all)")
    ap.add_argument("--out", type=Path, help="also write the Markdown table here")
    ap.add_argument("--set", action="append", default=[], metavar="MESHFIT_X=V",
                    help="an extra server setting for every scenario (repeatable)")
    ap.add_argument("--probe-child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.probe_child:
        return probe_child(args.probe_child)
    args.scenario = list(dict.fromkeys(args.scenario or SCENARIOS))
    extra = {}
    for item in args.set:
        k, sep, v = item.partition("=")
        if not sep or not k.startswith("MESHFIT_") or k == "MESHFIT_ADDR":
            ap.error(f"--set {item!r}: expected MESHFIT_NAME=VALUE (not MESHFIT_ADDR)")
        extra[k] = v
    wrk = shutil.which("wrk")
    if "cached" in args.scenario and not wrk:
        sys.exit("wrk not found; the `cached` scenario needs it: `sudo apt-get install wrk` (Debian/Ubuntu), "
                 "`brew install wrk` (macOS), or leave it out with --scenario ...")
    if not sys.platform.startswith("linux"):
        sys.exit("this script reads /proc: Linux only")
    limit = raise_own_fd_limit()
    if limit < 4096:
        print(f"warning: the client may open only {limit} files; idle_slow needs about 1,500", file=sys.stderr)
    binary = args.binary.resolve() if args.binary else build()
    if not binary.is_file():
        sys.exit(f"no binary at {binary}")

    def on_term(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, on_term)
    try:
        asyncio.run(main_async(args, binary, wrk, extra))
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        sys.exit(130)
    finally:
        _kill_leftovers()


if __name__ == "__main__":
    main()
