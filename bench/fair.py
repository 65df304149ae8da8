#!/usr/bin/env python3
"""Fairness under a flood, and the size of a stream's last event. Run by hand, never in CI.

    python3 bench/fair.py                       # builds target/release/meshfit
    python3 bench/fair.py --binary /path/to/meshfit --tries 20

A server with 2 workers, API keys A and B and the default client share (0.5): A posts six
jobs of 2·10^6 vertices (`sin(20*x)*cos(20*y)+i`) through POST /v1/jobs; then B asks for a
10-vertex mesh (a new function each time, so the cache never answers), once every half
second, `--tries` times. Printed: B's latencies (median, 95th percentile, largest) and how many
of A's jobs had finished when B's last answer came. Then, on a fresh server, the bytes of
the final `result` event of a 10^6-vertex stream (POST /v1/meshes with Accept:
text/event-stream), light by default and with `?inline=mesh`.

Python 3.11 standard library only.
"""

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KEY_A, KEY_B = "bench-key-a-0123456789", "bench-key-b-0123456789"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(binary, keys):
    port = free_port()
    env = {"PATH": os.environ.get("PATH", ""), "MESHFIT_ADDR": f"127.0.0.1:{port}", "MESHFIT_WORKERS": "2",
           "MESHFIT_LOG": "warn", "MESHFIT_SHUTDOWN_GRACE_MS": "1000"}
    if keys:
        env["MESHFIT_API_KEYS"] = f"{KEY_A},{KEY_B}"
    server = subprocess.Popen([binary, "serve"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    for _ in range(400):
        try:
            urllib.request.urlopen(f"{base}/healthz", timeout=1)
            return server, base
        except OSError:
            time.sleep(0.05)
    raise SystemExit("the server did not start")


def call(base, path, body=None, key=None, accept=None):
    headers = {"content-type": "application/json"}
    if key:
        headers["authorization"] = f"Bearer {key}"
    if accept:
        headers["accept"] = accept
    data = json.dumps(body).encode() if body is not None else None
    request = urllib.request.Request(base + path, data=data, headers=headers)
    with urllib.request.urlopen(request, timeout=600) as response:
        return response.read()


def flood(binary, tries):
    server, base = start(binary, keys=True)
    try:
        ids = []
        for i in range(6):
            body = {"function": f"sin(20*x)*cos(20*y)+{i}", "max_vertices": 2_000_000}
            ids.append(json.loads(call(base, "/v1/jobs", body, key=KEY_A))["id"])
        time.sleep(0.5)
        latencies = []
        for i in range(tries):
            start_at = time.perf_counter()
            call(base, "/v1/meshes", {"function": f"x*y+{i}", "max_vertices": 10}, key=KEY_B)
            latencies.append(time.perf_counter() - start_at)
            time.sleep(0.5)
        done = sum(
            json.loads(call(base, f"/v1/jobs/{i}", key=KEY_A))["status"] == "succeeded" for i in ids
        )
        return latencies, done
    finally:
        server.terminate()
        server.wait()


def last_event(binary, query):
    server, base = start(binary, keys=False)
    try:
        body = {"function": "sin(20*x)*cos(20*y)", "max_vertices": 1_000_000}
        stream = call(base, f"/v1/meshes{query}", body, accept="text/event-stream")
        events = stream.split(b"\n\n")
        final = [e for e in events if e.startswith(b"event: result")][-1]
        return len(final)
    finally:
        server.terminate()
        server.wait()


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--binary")
    p.add_argument("--tries", type=int, default=20)
    args = p.parse_args()
    binary = args.binary
    if not binary:
        subprocess.run(["cargo", "build", "--release", "--locked", "--quiet"], cwd=ROOT, check=True)
        binary = str(ROOT / "target" / "release" / "meshfit")
    latencies, done = flood(binary, args.tries)
    ms = sorted(l * 1e3 for l in latencies)
    p95 = ms[min(len(ms) - 1, round(0.95 * (len(ms) - 1)))]
    print(f"B's 10-vertex mesh behind A's six 2e6-vertex jobs, {len(ms)} tries: "
          f"median {statistics.median(ms):.1f} ms, p95 {p95:.1f} ms, largest {ms[-1]:.1f} ms; "
          f"A's jobs finished by then: {done} of 6")
    light, inline = last_event(binary, ""), last_event(binary, "?inline=mesh")
    print(f"final event of a 1e6-vertex stream: {light} bytes (light), {inline / 1e6:.1f} MB (?inline=mesh)")


if __name__ == "__main__":
    main()
