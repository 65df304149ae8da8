#!/usr/bin/env python3
"""A 4097 x 4097 heightmap to a mesh, end to end, as a grid file and as JSON.

Run by hand, never in CI:

    python3 -m venv bench/.venv && bench/.venv/bin/pip install numpy
    bench/.venv/bin/python bench/upload.py

It builds the release binary and samples Franke's function on 4097 x 4097 nodes twice: as
16-bit integers (0..65535) written into a PNG (numpy and zlib, no imaging library) and into
the API's JSON, and as f64 written into a .npy and into JSON at full precision (the 350 MB
body). It times `curl` posting each to a fresh server on a loopback port: upload, decode,
hash, refine and response (a new server each run, since a pair carries the same values and
so the same job id). Each at 10^5 vertices and at 4 (no refinement: what the body's format
alone costs). Three runs each, alternating; it prints the medians and the ratios.
"""

import json
import os
import socket
import statistics
import struct
import subprocess
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TARGET = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
MESHFIT = TARGET / "release" / "meshfit"
N = 4097
VERTICES = 100_000


def franke(x, y):
    a, b = 9 * x, 9 * y
    return (0.75 * np.exp(-((a - 2) ** 2 + (b - 2) ** 2) / 4) + 0.75 * np.exp(-((a + 1) ** 2) / 49 - (b + 1) / 10)
            + 0.5 * np.exp(-((a - 7) ** 2 + (b - 3) ** 2) / 4) - 0.2 * np.exp(-((a - 4) ** 2) - (b - 7) ** 2))


def heights():
    """Row j is y_j, bottom first (the JSON order); values scaled to 16 bits."""
    t = np.linspace(0, 1, N)
    z = franke(t[None, :], t[:, None])
    return np.round((z - z.min()) / (z.max() - z.min()) * 65535).astype(np.uint16)


def png16(rows_top_first):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    h, w = rows_top_first.shape
    raw = np.zeros((h, 1 + 2 * w), dtype=np.uint8)
    raw[:, 1:] = rows_top_first.astype(">u2").view(np.uint8).reshape(h, 2 * w)
    ihdr = struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw.tobytes(), 6))
            + chunk(b"IEND", b""))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def timed(curl_args):
    port = free_port()
    env = dict(os.environ, MESHFIT_ADDR=f"127.0.0.1:{port}", MESHFIT_MAX_BODY_BYTES=str(1 << 30),
               MESHFIT_LOG_FORMAT="json", RUST_LOG="warn")
    server = subprocess.Popen([str(MESHFIT)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(200):
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.1).close()
                break
            except OSError:
                time.sleep(0.05)
        out = subprocess.run(["curl", "-s", "-o", "/dev/null", "-w", "%{http_code} %{time_total}",
                              f"http://127.0.0.1:{port}/v1/meshes", *curl_args],
                             check=True, capture_output=True, text=True).stdout.split()
        assert out[0] == "200", out
        return float(out[1])
    finally:
        server.terminate()
        server.wait()


def main():
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    ints = heights()
    t = np.linspace(0, 1, N)
    floats = franke(t[None, :], t[:, None])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        png_path, npy_path = Path(tmp, "franke.png"), Path(tmp, "franke.npy")
        png_path.write_bytes(png16(ints[::-1]))
        np.save(npy_path, floats[::-1])
        for vertices in (VERTICES, 4):
            pairs = []
            for name, path, values in (("16-bit png", png_path, ints), ("f64 npy", npy_path, floats)):
                json_path = Path(tmp, "grid.json")
                body = {"grid": {"nx": N, "ny": N, "values": values.ravel().tolist()}, "max_vertices": vertices}
                json_path.write_text(json.dumps(body, separators=(",", ":")))
                request = json.dumps({"max_vertices": vertices})
                file_runs, json_runs = [], []
                for _ in range(3):
                    file_runs.append(timed(["-F", f"request={request}", "-F", f"grid=@{path}"]))
                    json_runs.append(timed(["-H", "content-type: application/json", "--data-binary", f"@{json_path}"]))
                pairs.append((name, path.stat().st_size, statistics.median(file_runs), json_path.stat().st_size,
                              statistics.median(json_runs)))
            rows.append((vertices, pairs))
    print(f"Franke on {N} x {N} nodes, POST /v1/meshes end to end, median of 3 (bench/upload.py):")
    print("| vertices | grid file | file size | file time | JSON size | JSON time | JSON / file |")
    print("|---|---|---|---|---|---|---|")
    for vertices, pairs in rows:
        for name, fsize, ftime, jsize, jtime in pairs:
            print(f"| {vertices} | {name} | {fsize / 1e6:.0f} MB | {ftime:.2f} s | {jsize / 1e6:.0f} MB | {jtime:.2f} s "
                  f"| {jtime / ftime:.1f}x |")


if __name__ == "__main__":
    main()
