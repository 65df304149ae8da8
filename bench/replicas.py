#!/usr/bin/env python3
"""Three replicas sharing through Redis behind nginx: cached throughput, and what one
replica's death costs the clients. Run by hand, never in CI.

    python3 bench/replicas.py                      # builds target/release/meshfit
    python3 bench/replicas.py --binary PATH --seconds 5

Python 3.11 standard library, plus Debian's redis-server, nginx and wrk on the PATH
(`apt-get install redis-server nginx wrk`). Everything listens on loopback ports: one
redis-server without persistence, three replicas (MESHFIT_WORKERS=1 each, lease 2 s) and
nginx with deploy/nginx.conf, its upstream pointed at the three replicas. Logs stay in the
directory printed at the end.

Scenarios:
  cached     POST {"function": "sin(5*x)*y", "max_vertices": 2000} once through nginx, then
             wrk -t2 -c64 for --seconds: through nginx to all three replicas, straight to one
             of them, and to one replica alone (no Redis, no nginx) for comparison. Each
             replica reads the result from Redis at most once (shared_hits), then answers
             from its own cache.
  death      A detached job (sin(40x)cos(40y), variation, 10^6 vertices) submitted through
             nginx; a client follows its events through nginx, reconnecting with
             Last-Event-ID as an EventSource does, while a second client sends cached
             requests through nginx without pause. The replica running the job gets SIGKILL
             once the job is running. Reported: the cached client's failures and latency
             around the kill, how long the job took without a death (a second, identical
             cluster), and how long the follower waited from the kill to the result.
"""

import argparse
import json
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LEASE_MS = 2000


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_port(port, what, timeout=20):
    deadline = time.time() + timeout
    while time.time() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return
        except OSError:
            time.sleep(0.05)
    sys.exit(f"{what} did not listen on {port}")


def request(url, body=None, method=None, timeout=60, headers=None):
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(url, data=data, method=method, headers=headers or {})
    if data is not None:
        req.add_header("content-type", "application/json")
    with urllib.request.urlopen(req, timeout=timeout) as r:
        return r.status, dict(r.headers), r.read()


def metric(port, name):
    _, _, text = request(f"http://127.0.0.1:{port}/metrics")
    for line in text.decode().splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return 0.0


class Cluster:
    """redis-server, three replicas and nginx in front, in `workdir`."""

    def __init__(self, binary, workdir, name):
        self.dir = os.path.join(workdir, name)
        os.makedirs(self.dir)
        os.chmod(self.dir, 0o777)
        self.procs = {}
        self.redis_port = free_port()
        self.spawn("redis", ["redis-server", "--port", str(self.redis_port), "--bind", "127.0.0.1",
                             "--save", "", "--appendonly", "no"], {})
        wait_port(self.redis_port, "redis-server")
        self.ports = []
        for k in range(3):
            port = free_port()
            env = {
                "MESHFIT_ADDR": f"127.0.0.1:{port}",
                "MESHFIT_WORKERS": "1",
                "MESHFIT_LOG": "warn",
                "MESHFIT_SHUTDOWN_GRACE_MS": "1000",
                "MESHFIT_REDIS_URL": f"redis://127.0.0.1:{self.redis_port}/",
                "MESHFIT_REDIS_LEASE_MS": str(LEASE_MS),
            }
            self.spawn(f"replica{k}", [binary, "serve"], env)
            wait_port(port, f"replica {k}")
            self.ports.append(port)
        for port in self.ports:
            wait_ready(port)
        self.lb_port = free_port()
        conf = open(os.path.join(ROOT, "deploy", "nginx.conf")).read()
        servers = "\n".join(f"        server 127.0.0.1:{p} max_fails=1 fail_timeout=5s;" for p in self.ports)
        conf = conf.replace("        server meshfit:8080 max_fails=1 fail_timeout=5s;", servers)
        conf = conf.replace("listen 8080;", f"listen 127.0.0.1:{self.lb_port};\n        access_log off;")
        conf = conf.replace("events {}", "events {}\npid %s/nginx.pid;\nerror_log %s/nginx-error.log;" % (self.dir, self.dir))
        temp = "".join(f"    {k}_temp_path {self.dir}/{k};\n" for k in ("client_body", "proxy", "fastcgi", "uwsgi", "scgi"))
        conf = conf.replace("http {\n", "http {\n" + temp)
        path = os.path.join(self.dir, "nginx.conf")
        open(path, "w").write(conf)
        self.spawn("nginx", ["nginx", "-c", path, "-p", self.dir, "-g", "daemon off;"], {})
        wait_port(self.lb_port, "nginx")

    def spawn(self, name, argv, env):
        log = open(os.path.join(self.dir, f"{name}.log"), "w")
        self.procs[name] = subprocess.Popen(argv, env={"PATH": os.environ["PATH"], **env}, stdout=log, stderr=log)

    def url(self, path):
        return f"http://127.0.0.1:{self.lb_port}{path}"

    def kill(self, port):
        name = f"replica{self.ports.index(port)}"
        self.procs[name].send_signal(signal.SIGKILL)
        self.procs[name].wait()

    def stop(self):
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in self.procs.values():
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()


def wait_ready(port):
    for _ in range(400):
        try:
            _, _, body = request(f"http://127.0.0.1:{port}/readyz", timeout=2)
            if json.loads(body).get("redis") == "up":
                return
        except (urllib.error.URLError, OSError):
            pass
        time.sleep(0.05)
    sys.exit(f"replica on {port} never saw redis")


WRK_POST = """
wrk.method = "POST"
wrk.body = '%s'
wrk.headers["content-type"] = "application/json"
"""


def wrk(url, seconds, body, workdir):
    script = os.path.join(workdir, "post.lua")
    open(script, "w").write(WRK_POST % json.dumps(body))
    out = subprocess.run(["wrk", "-t2", "-c64", f"-d{seconds}s", "--latency", "-s", script, url],
                         capture_output=True, text=True, check=True).stdout
    rps = float(next(l for l in out.splitlines() if l.startswith("Requests/sec")).split()[1])
    p50 = next(l for l in out.splitlines() if l.strip().startswith("50%")).split()[1]
    p99 = next(l for l in out.splitlines() if l.strip().startswith("99%")).split()[1]
    errors = sum(int(x) for l in out.splitlines() if "Socket errors" in l
                 for x in l.replace(",", " ").split() if x.isdigit())
    non2xx = next((int(l.split()[-1]) for l in out.splitlines() if "Non-2xx" in l), 0)
    return rps, p50, p99, errors + non2xx


def cached(binary, workdir, seconds):
    body = {"function": "sin(5*x)*y", "max_vertices": 2000}
    cluster = Cluster(binary, workdir, "cached")
    try:
        request(cluster.url("/v1/meshes"), body)
        through = wrk(cluster.url("/v1/meshes"), seconds, body, cluster.dir)
        direct = wrk(f"http://127.0.0.1:{cluster.ports[0]}/v1/meshes", seconds, body, cluster.dir)
        runs = sum(metric(p, "meshfit_engine_runs_total") for p in cluster.ports)
        shared = sum(metric(p, "meshfit_shared_hits_total") for p in cluster.ports)
    finally:
        cluster.stop()
    # One replica alone, no Redis, no nginx.
    port = free_port()
    log = open(os.path.join(workdir, "alone.log"), "w")
    env = {"PATH": os.environ["PATH"], "MESHFIT_ADDR": f"127.0.0.1:{port}", "MESHFIT_WORKERS": "1",
           "MESHFIT_LOG": "warn"}
    alone = subprocess.Popen([binary, "serve"], env=env, stdout=log, stderr=log)
    try:
        wait_port(port, "the lone replica")
        request(f"http://127.0.0.1:{port}/v1/meshes", body)
        single = wrk(f"http://127.0.0.1:{port}/v1/meshes", seconds, body, workdir)
    finally:
        alone.send_signal(signal.SIGTERM)
        alone.wait()
    print("## cached requests (wrk -t2 -c64, %d s, 2 cores shared by wrk, nginx and the servers)\n" % seconds)
    print("| target | req/s | p50 | p99 | errors + non-2xx |")
    print("|---|---|---|---|---|")
    print("| nginx → 3 replicas + Redis | %.0f | %s | %s | %d |" % through)
    print("| one of the 3, without nginx | %.0f | %s | %s | %d |" % direct)
    print("| one replica alone | %.0f | %s | %s | %d |" % single)
    print(f"\nengine runs across the three: {runs:.0f}; results read from Redis: {shared:.0f}\n")


class Follower(threading.Thread):
    """Follows a job's events through nginx, reconnecting with Last-Event-ID."""

    def __init__(self, url):
        super().__init__(daemon=True)
        self.url, self.last_id, self.reconnects, self.result_at = url, None, 0, None

    def run(self):
        while self.result_at is None:
            headers = {"accept": "text/event-stream"}
            if self.last_id is not None:
                headers["last-event-id"] = self.last_id
            try:
                req = urllib.request.Request(self.url, headers=headers)
                with urllib.request.urlopen(req, timeout=120) as r:
                    event = None
                    for raw in r:
                        line = raw.decode().rstrip("\n")
                        if line.startswith("id:"):
                            self.last_id = line[3:].strip()
                        elif line.startswith("event:"):
                            event = line[6:].strip()
                        elif line.startswith("data:") and event == "result":
                            self.result_at = time.time()
                            return
            except (urllib.error.URLError, OSError, ConnectionError):
                pass
            self.reconnects += 1
            time.sleep(0.1)


class Prober(threading.Thread):
    """Cached POSTs through nginx, one after another, timing each."""

    def __init__(self, url, body):
        super().__init__(daemon=True)
        self.url, self.body, self.samples, self.stop = url, body, [], False

    def run(self):
        while not self.stop:
            start = time.time()
            try:
                status, _, _ = request(self.url, self.body, timeout=10)
                ok = status == 200
            except (urllib.error.URLError, OSError):
                ok = False
            self.samples.append((start, time.time() - start, ok))


def job_time(binary, workdir, job):
    """How long the job takes on a cluster where nobody dies (submit to result)."""
    cluster = Cluster(binary, workdir, "baseline")
    try:
        start = time.time()
        _, _, body = request(cluster.url("/v1/jobs"), job)
        follower = Follower(cluster.url(f"/v1/jobs/{json.loads(body)['id']}/events"))
        follower.start()
        follower.join()
        return follower.result_at - start
    finally:
        cluster.stop()


def death(binary, workdir):
    job = {"function": "sin(40*x)*cos(40*y)", "criterion": "variation", "max_vertices": 1_000_000}
    baseline = job_time(binary, workdir, job)
    cluster = Cluster(binary, workdir, "death")
    cached_body = {"function": "sin(5*x)*y", "max_vertices": 2000}
    try:
        request(cluster.url("/v1/meshes"), cached_body)
        prober = Prober(cluster.url("/v1/meshes"), cached_body)
        prober.start()
        _, _, body = request(cluster.url("/v1/jobs"), job)
        jid = json.loads(body)["id"]
        follower = Follower(cluster.url(f"/v1/jobs/{jid}/events"))
        follower.start()
        owner = None
        while owner is None:
            owner = next((p for p in cluster.ports if metric(p, "meshfit_jobs_running") == 1), None)
            time.sleep(0.02)
        time.sleep(0.3)
        killed_at = time.time()
        cluster.kill(owner)
        follower.join(timeout=120)
        time.sleep(1)
        prober.stop = True
        prober.join()
        takeovers = sum(metric(p, "meshfit_takeovers_total") for p in cluster.ports if p != owner)
    finally:
        cluster.stop()
    around = [s for s in prober.samples if killed_at - 1 <= s[0] <= killed_at + 3]
    failed = sum(1 for s in around if not s[2])
    latencies = sorted(s[1] * 1e3 for s in around if s[2])
    print("## one replica's death (SIGKILL of the replica running a 10^6-vertex job)\n")
    print(f"- lease {LEASE_MS} ms; the job alone, submit to result: {baseline * 1e3:.0f} ms")
    print(f"- follower through nginx: result {(follower.result_at - killed_at) * 1e3:.0f} ms after the kill, "
          f"{follower.reconnects} reconnects; takeovers: {takeovers:.0f}")
    print(f"- cached requests from 1 s before to 3 s after the kill: {len(around)}, failed {failed}, "
          f"p50 {statistics.median(latencies):.1f} ms, max {latencies[-1]:.1f} ms")
    print(f"- cached requests over the whole run: {len(prober.samples)}, "
          f"failed {sum(1 for s in prober.samples if not s[2])}\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--binary", help="a built meshfit (default: cargo build --release)")
    parser.add_argument("--seconds", type=int, default=10, help="wrk's duration")
    parser.add_argument("--scenario", nargs="*", default=["cached", "death"])
    args = parser.parse_args()
    for tool in ("redis-server", "nginx", "wrk"):
        if shutil.which(tool) is None:
            sys.exit(f"{tool} is not installed (apt-get install redis-server nginx wrk)")
    binary = args.binary
    if binary is None:
        subprocess.run(["cargo", "build", "--release", "--locked"], cwd=ROOT, check=True)
        binary = os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")), "release", "meshfit")
    workdir = tempfile.mkdtemp(prefix="meshfit-replicas-")
    os.chmod(workdir, 0o755)
    if "cached" in args.scenario:
        cached(binary, workdir, args.seconds)
    if "death" in args.scenario:
        death(binary, workdir)
    print(f"logs: {workdir}")


if __name__ == "__main__":
    main()
