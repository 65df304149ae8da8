#!/usr/bin/env python3
"""A DEM file larger than meshfit keeps, served by blocks: start-up, memory and tile latency.

Builds a tiled, deflate-compressed GeoTIFF (512 x 512 blocks, as a COG has them) of a real DEM
resampled bilinearly to SIZE x SIZE, names it to `meshfit serve --dataset big=PATH` and asks
for tiles over HTTP, uncached: a root, a tile of each level down to the deepest, and a run of
the deepest. Prints the file's size, the decoded size, the time to start (the one read through
the file), the server's resident memory after start and at its peak (VmHWM), and each tile's
latency.

Run by hand, never in CI (it builds the release binary and writes a file of some GB):

    bench/.venv/bin/python bench/big_dem.py --size 20000          # 1.6 GB decoded as f32
    bench/.venv/bin/python bench/big_dem.py --dem other.tif --size 8000 --no-build
"""

import argparse
import json
import os
import socket
import statistics
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import tifffile

ROOT = Path(__file__).resolve().parent.parent
MESHFIT = ROOT / "target" / "release" / "meshfit"


def resampled(path, size):
    """The DEM's heights resampled bilinearly to size x size, rows from the north, and its
    bounds (west, south, east, north) through the corner pixels' centres."""
    with tifffile.TiffFile(path) as tif:
        page = tif.pages[0]
        heights = page.asarray().astype(np.float32)
        sx, sy, _ = page.tags["ModelPixelScaleTag"].value
        _, _, _, x0, y0, _ = page.tags["ModelTiepointTag"].value
    ny, nx = heights.shape
    west, north = x0 + sx / 2, y0 - sy / 2
    east, south = west + (nx - 1) * sx, north - (ny - 1) * sy
    out = np.empty((size, size), dtype=np.float32)
    u = np.linspace(0, nx - 1, size)
    i = np.minimum(u.astype(int), nx - 2)
    fx = (u - i).astype(np.float32)
    for row0 in range(0, size, 1024):
        v = np.linspace(0, ny - 1, size)[row0 : row0 + 1024]
        j = np.minimum(v.astype(int), ny - 2)
        fy = (v - j).astype(np.float32)[:, None]
        top = heights[j][:, i] * (1 - fx) + heights[j][:, i + 1] * fx
        bottom = heights[j + 1][:, i] * (1 - fx) + heights[j + 1][:, i + 1] * fx
        out[row0 : row0 + len(v)] = top * (1 - fy) + bottom * fy
    return out, (west, south, east, north)


def write_cog(path, heights, bounds):
    """A tiled, deflate GeoTIFF in EPSG:4326 (pixel is area)."""
    west, south, east, north = bounds
    ny, nx = heights.shape
    sx, sy = (east - west) / (nx - 1), (north - south) / (ny - 1)
    tifffile.imwrite(
        path,
        heights,
        tile=(512, 512),
        compression="zlib",
        extratags=[
            (33550, "d", 3, (sx, sy, 0.0)),
            (33922, "d", 6, (0.0, 0.0, 0.0, west - sx / 2, north + sy / 2, 0.0)),
            (34735, "H", 12, (1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326)),
        ],
    )


def memory(pid):
    """Resident and peak resident memory of a process, in MB."""
    status = Path(f"/proc/{pid}/status").read_text()
    value = lambda key: int(next(l for l in status.splitlines() if l.startswith(key)).split()[1]) / 1024
    return value("VmRSS:"), value("VmHWM:")


def timed_get(url):
    start = time.perf_counter()
    body = urllib.request.urlopen(urllib.request.Request(url, headers={"accept-encoding": "gzip"})).read()
    return (time.perf_counter() - start) * 1e3, len(body)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--dem", default=str(ROOT / "examples/grids/dem-4326.tif"))
    p.add_argument("--size", type=int, default=20000)
    p.add_argument("--no-build", action="store_true")
    args = p.parse_args()
    if not args.no_build:
        subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    with tempfile.TemporaryDirectory(prefix="meshfit-big-") as tmp:
        path = Path(tmp) / "big.tif"
        heights, bounds = resampled(args.dem, args.size)
        write_cog(path, heights, bounds)
        decoded = heights.size * 8
        del heights
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        env = dict(os.environ, MESHFIT_ADDR=f"127.0.0.1:{port}", MESHFIT_LOG="warn")
        start = time.perf_counter()
        server = subprocess.Popen(
            [str(MESHFIT), "serve", "--dataset", f"big={path}"], env=env, stdout=subprocess.DEVNULL
        )
        base = f"http://127.0.0.1:{port}"
        try:
            while True:
                try:
                    urllib.request.urlopen(f"{base}/healthz", timeout=1)
                    break
                except OSError:
                    if server.poll() is not None:
                        raise SystemExit("the server stopped")
                    time.sleep(0.05)
            started = time.perf_counter() - start
            rss, _ = memory(server.pid)
            info = json.loads(urllib.request.urlopen(f"{base}/v1/datasets/big").read())
            layer = json.loads(urllib.request.urlopen(f"{base}/v1/tiles/big/layer.json").read())
            print(
                f"file {path.stat().st_size / 1e6:.0f} MB ({args.size} x {args.size}, tiled 512, deflate), "
                f"{decoded / 1e6:.0f} MB decoded as f64; levels 0..{info['max_zoom']}"
            )
            print(f"start-up (one read through the file): {started:.1f} s; resident after: {rss:.0f} MB")
            print()
            print("| tile | latency (ms) | gzip bytes |")
            print("|---|---|---|")
            tile = lambda z, x, y: f"{base}/v1/tiles/big/{z}/{x}/{y}.terrain?extensions=octvertexnormals-metadata"
            for z, ranges in enumerate(layer["available"]):
                r = ranges[0]
                x, y = (r["startX"] + r["endX"]) // 2, (r["startY"] + r["endY"]) // 2
                ms, n = timed_get(tile(z, x, y))
                print(f"| {z}/{x}/{y} | {ms:.0f} | {n} |")
            deepest = layer["available"][-1][0]
            z = len(layer["available"]) - 1
            columns = range(deepest["startX"], min(deepest["endX"] + 1, deepest["startX"] + 50))
            run = [timed_get(tile(z, x, deepest["startY"]))[0] for x in columns]
            _, peak = memory(server.pid)
            print()
            print(f"{len(run)} neighbouring tiles of level {z}: median {statistics.median(run):.1f} ms, largest {max(run):.1f} ms")
            print(f"peak resident memory: {peak:.0f} MB")
        finally:
            server.terminate()
            server.wait()


if __name__ == "__main__":
    main()
