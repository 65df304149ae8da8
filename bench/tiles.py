#!/usr/bin/env python3
"""meshfit's terrain pyramid beside the usual pipeline (pydelatin per tile at the same
per-level error, encoded with quantized-mesh-encoder), measured as a terrain user measures:
per level, vertices, gzip bytes, the largest error at the DEM's own samples, cracks between
neighbours, and time.

Run by hand, never in CI (it builds the release binary):

    python3 -m venv bench/.venv
    bench/.venv/bin/pip install numpy pydelatin quantized-mesh-encoder matplotlib tifffile
    bench/.venv/bin/python bench/tiles.py                       # examples/grids/dem-4326.tif
    bench/.venv/bin/python bench/tiles.py --dem dem.tif --no-build

The DEM is a GeoTIFF in EPSG:4326 (pixel is area). Both pipelines mesh the same heights: the
DEM sampled bilinearly on meshfit's per-level lattice (the same power of two of steps a tile
side, from 64 to 1,024, as fine as the DEM's pixel), to the same tolerance, the level's
geometric error (Cesium's 77,067.34 m / 2^z). pydelatin meshes each tile's lattice on its own,
as per-tile scripts do; meshfit fixes each side from its own values first.

- error: max |F_n - h| over the DEM's samples (pixel centres) inside each tile, F_n the tile's
  mesh interpolated linearly (matplotlib), h the DEM's value there; the worst tile of the
  level, in metres and as a fraction of the level's error.
- cracks: along each side neighbours share (east and north), both tiles' meshes evaluated at
  401 points a hair inside each; a side is cracked where they differ by more than the two
  tiles' height quantization, and the largest gap of the level is printed.
- time: meshfit's `tiles` command for the whole pyramid on every core; pydelatin's lattice
  sampling, meshing and encoding of every tile, one process per core.
- on demand: `meshfit serve` (release build) with the DEM uploaded, each tile of the deepest
  level asked for once over HTTP (uncached, gzipped, both extensions): the median and largest
  latency, beside pydelatin's time for the same tile in this process (lattice, or window,
  meshing and encoding), median.
"""

import argparse
import socket
import statistics
import urllib.request
import gzip
import io
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np
import tifffile
from matplotlib.tri import LinearTriInterpolator, Triangulation

ROOT = Path(__file__).resolve().parent.parent
MESHFIT = ROOT / "target" / "release" / "meshfit"
# pydelatin's lattice: meshfit's steps a side (src/tiles/pyramid.rs), times this (to measure
# what a finer lattice would buy, after changing meshfit's alike).
OVERSAMPLE = float(os.environ.get("OVERSAMPLE", "1"))
LEVEL_ZERO_ERROR = 6378137.0 * 2 * math.pi * 0.25 / (65 * 2)


def read_dem(path):
    """Heights (rows from the north), the first pixel centre's lon/lat and the pixel size."""
    with tifffile.TiffFile(path) as tif:
        page = tif.pages[0]
        heights = page.asarray().astype(np.float64)
        sx, sy, _ = page.tags["ModelPixelScaleTag"].value
        _, _, _, x0, y0, _ = page.tags["ModelTiepointTag"].value
    return heights, x0 + sx / 2, y0 - sy / 2, sx, sy


class Dem:
    def __init__(self, path):
        self.h, self.lon0, self.lat0, self.sx, self.sy = read_dem(path)
        self.ny, self.nx = self.h.shape
        self.west, self.north = self.lon0, self.lat0
        self.east = self.lon0 + (self.nx - 1) * self.sx
        self.south = self.lat0 - (self.ny - 1) * self.sy

    def bilinear(self, lon, lat):
        """The DEM at points; beyond it, its nearest edge fading to 0 over its larger side, as
        meshfit's tiles::mesher::height."""
        off = np.maximum.reduce([self.west - lon, lon - self.east, self.south - lat, lat - self.north])
        weight = np.where(off <= 0, 1.0, np.maximum(1.0 - off / max(self.east - self.west, self.north - self.south), 0.0))
        return self._clamped(lon, lat) * weight

    def _clamped(self, lon, lat):
        u = np.clip((lon - self.lon0) / self.sx, 0, self.nx - 1)
        v = np.clip((self.lat0 - lat) / self.sy, 0, self.ny - 1)
        i = np.minimum(u.astype(int), self.nx - 2)
        j = np.minimum(v.astype(int), self.ny - 2)
        fx, fy = u - i, v - j
        h = self.h
        top = h[j, i] * (1 - fx) + h[j, i + 1] * fx
        bottom = h[j + 1, i] * (1 - fx) + h[j + 1, i + 1] * fx
        return top * (1 - fy) + bottom * fy

    def samples_in(self, b):
        """The DEM's pixel centres inside bounds b: (lon, lat, height)."""
        cols = np.arange(self.nx)
        rows = np.arange(self.ny)
        lons = self.lon0 + cols * self.sx
        lats = self.lat0 - rows * self.sy
        ci = cols[(lons >= b[0]) & (lons <= b[2])]
        ri = rows[(lats >= b[1]) & (lats <= b[3])]
        if len(ci) == 0 or len(ri) == 0:
            return None
        jj, ii = np.meshgrid(ri, ci, indexing="ij")
        return (self.lon0 + ii * self.sx).ravel(), (self.lat0 - jj * self.sy).ravel(), self.h[jj, ii].ravel()


def bounds(z, x, y):
    size = 180.0 / 2**z
    west, south = -180.0 + x * size, -90.0 + y * size
    return (west, south, west + size, south + size)


def steps(z, dem):
    pixels = math.ceil(OVERSAMPLE * (180.0 / 2**z) / min(dem.sx, dem.sy))
    return min(max(1 << max(min(pixels, 1024) - 1, 0).bit_length(), 64), 1024)


def decode(data):
    """(vertices [lon, lat, h], triangles) of a quantized-mesh tile and its bounds."""
    (min_h, max_h) = struct.unpack_from("<ff", data, 24)
    n = struct.unpack_from("<I", data, 88)[0]
    pos = 92
    streams = []
    for _ in range(3):
        raw = np.frombuffer(data, dtype="<u2", count=n, offset=pos).astype(np.int64)
        pos += 2 * n
        zz = (raw >> 1) ^ (-(raw & 1))
        streams.append(np.cumsum(zz))
    wide = n > 65536
    size = 4 if wide else 2
    if pos % size:
        pos += size - pos % size
    t = struct.unpack_from("<I", data, pos)[0]
    pos += 4
    codes = np.frombuffer(data, dtype="<u4" if wide else "<u2", count=3 * t, offset=pos).astype(np.int64)
    indices = np.empty_like(codes)
    highest = 0
    for k, c in enumerate(codes):
        indices[k] = highest - c
        if c == 0:
            highest += 1
    u, v, h = streams
    heights = min_h + h / 32767.0 * (max_h - min_h)
    return u, v, heights, indices.reshape(-1, 3)


def placed(u, v, heights, b):
    return b[0] + u / 32767.0 * (b[2] - b[0]), b[1] + v / 32767.0 * (b[3] - b[1]), heights


def max_error(dem, lon, lat, h, tris, b):
    samples = dem.samples_in(b)
    if samples is None:
        return 0.0
    tri = Triangulation(lon, lat, tris)
    f = LinearTriInterpolator(tri, h)(samples[0], samples[1])
    err = np.abs(np.ma.filled(f, np.nan) - samples[2])
    return float(np.nanmax(err)) if np.isfinite(err).any() else 0.0


def delatin_tile(args):
    """The usual pipeline for one tile: lattice, pydelatin, quantized-mesh-encoder."""
    path, z, x, y = args
    from pydelatin import Delatin

    dem = DEMS[path]
    b = bounds(z, x, y)
    n = steps(z, dem) + 1
    lon = np.linspace(b[0], b[2], n)
    lat = np.linspace(b[3], b[1], n)  # rows from the north, as a raster
    grid_lon, grid_lat = np.meshgrid(lon, lat)
    heights = dem.bilinear(grid_lon, grid_lat).astype(np.float32)
    tin = Delatin(heights, height=n, width=n, max_error=LEVEL_ZERO_ERROR / 2**z)
    verts, tris = tin.vertices, tin.triangles
    positions = np.stack(
        # pydelatin's y counts rows from the last (the south), x columns from the west.
        [b[0] + verts[:, 0] / (n - 1) * (b[2] - b[0]), b[1] + verts[:, 1] / (n - 1) * (b[3] - b[1]), verts[:, 2]], axis=1
    )
    return (z, x, y), encoded(positions, tris, b)


def delatin_window(args):
    """The per-tile script on the DEM's own samples: the raster window of pixel centres inside
    the tile, pydelatin to the level's error there. Within it at every sample by
    construction: the vertices the same samples and error need. Its windows do not reach the
    tile's sides, so neighbours crack."""
    path, z, x, y = args
    from pydelatin import Delatin

    dem = DEMS[path]
    b = bounds(z, x, y)
    lons = dem.lon0 + np.arange(dem.nx) * dem.sx
    lats = dem.lat0 - np.arange(dem.ny) * dem.sy
    ci = np.nonzero((lons >= b[0]) & (lons <= b[2]))[0]
    ri = np.nonzero((lats >= b[1]) & (lats <= b[3]))[0]
    if len(ci) < 2 or len(ri) < 2:
        return (z, x, y), None
    window = dem.h[ri[0] : ri[-1] + 1, ci[0] : ci[-1] + 1].astype(np.float32)
    h, w = window.shape
    tin = Delatin(window, height=h, width=w, max_error=WINDOW_ERROR * LEVEL_ZERO_ERROR / 2**z)
    verts, tris = tin.vertices, tin.triangles
    # Rows from the north in the window; pydelatin's y counts from the last row.
    positions = np.stack(
        [lons[ci[0]] + verts[:, 0] * dem.sx, lats[ri[-1]] + verts[:, 1] * dem.sy, verts[:, 2]], axis=1
    )
    return (z, x, y), encoded(positions, tris, b)


def encoded(positions, tris, b):
    """A tile's mesh as quantized-mesh-encoder writes it."""
    from quantized_mesh_encoder import encode

    # quantized-mesh-encoder writes indices by high-water mark as given: the vertices must be
    # numbered in the order the triangles first use them, which pydelatin's are not.
    order, first = [], {}
    for k in tris.ravel():
        if k not in first:
            first[k] = len(order)
            order.append(k)
    tris = np.vectorize(first.get)(tris)
    positions = positions[order]
    out = io.BytesIO()
    encode(out, positions.astype(np.float32), tris.astype(np.uint32), bounds=b)
    return out.getvalue()


DEMS = {}

# The DEM window's max_error, as a fraction of the level's (--window-error): pydelatin's own
# check is looser than its target (1.08x at level 14), so a tighter one compares vertices at
# an error that holds. Set before the worker processes fork.
WINDOW_ERROR = 1.0


def init(path):
    DEMS[path] = Dem(path)


def measure(name, tiles, dem, levels):
    rows = []
    for z in levels:
        at = {k: v for k, v in tiles.items() if k[0] == z}
        if not at:
            continue
        verts = gz = inner = 0
        worst = 0.0
        meshes = {}
        for (zz, x, y), data in at.items():
            b = bounds(zz, x, y)
            u, v, h, tris = decode(data)
            lon, lat, hh = placed(u, v, h, b)
            meshes[(x, y)] = (LinearTriInterpolator(Triangulation(lon, lat, tris), hh), b, float(h.max() - h.min()))
            verts += len(u)
            # Tiles wholly on the DEM: no fading beyond it, and a window as large as the tile.
            if dem.west <= b[0] and b[2] <= dem.east and dem.south <= b[1] and b[3] <= dem.north:
                inner += len(u)
            gz += len(gzip.compress(data))
            worst = max(worst, max_error(dem, lon, lat, hh, tris, b))
        # Each side neighbours share, seen from both: the largest height gap along it, and
        # whether it is more than the two tiles' height quantization (a crack).
        cracked = shared = 0
        gap = 0.0
        for (x, y), (f, b, span) in meshes.items():
            for other, east in (((x + 1, y), True), ((x, y + 1), False)):
                if other not in meshes:
                    continue
                g, b2, span2 = meshes[other]
                shared += 1
                eps = 1e-7 * (b[2] - b[0])
                t = np.linspace(0.0, 1.0, 401)
                if east:
                    lat = b[1] + t * (b[3] - b[1])
                    mine, theirs = f(np.full_like(lat, b[2] - eps), lat), g(np.full_like(lat, b2[0] + eps), lat)
                else:
                    lon = b[0] + t * (b[2] - b[0])
                    mine, theirs = f(lon, np.full_like(lon, b[3] - eps)), g(lon, np.full_like(lon, b2[1] + eps))
                d = float(np.nanmax(np.abs(np.ma.filled(mine, np.nan) - np.ma.filled(theirs, np.nan))))
                gap = max(gap, d)
                if d > (span + span2) / 32767.0 + 1e-6:
                    cracked += 1
        if name.endswith("window"):
            # Its meshes stop at the outer pixel centres: neighbours leave a gap, not measured.
            cracked, gap = "gap", float("nan")
        rows.append((name, z, len(at), verts, inner, gz, worst, worst / (LEVEL_ZERO_ERROR / 2**z), cracked, shared, gap))
    return rows


def on_demand(binary, path, tiles):
    """Latencies of uncached tiles from a fresh `meshfit serve`, in ms, in the order given."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = dict(os.environ, MESHFIT_ADDR=f"127.0.0.1:{port}", MESHFIT_LOG="warn")
    server = subprocess.Popen([binary, "serve"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    try:
        for _ in range(200):
            try:
                urllib.request.urlopen(f"{base}/healthz", timeout=1)
                break
            except OSError:
                time.sleep(0.05)
        boundary = "meshfit-bench"
        body = (
            f"--{boundary}\r\nContent-Disposition: form-data; name=\"grid\"; filename=\"dem.tif\"\r\n"
            "Content-Type: image/tiff\r\n\r\n"
        ).encode() + Path(path).read_bytes() + f"\r\n--{boundary}--\r\n".encode()
        request = urllib.request.Request(
            f"{base}/v1/datasets", data=body, headers={"content-type": f"multipart/form-data; boundary={boundary}"}
        )
        dataset = json.loads(urllib.request.urlopen(request).read())["id"]
        latencies = []
        for z, x, y in tiles:
            url = f"{base}/v1/tiles/{dataset}/{z}/{x}/{y}.terrain?extensions=octvertexnormals-metadata"
            start = time.perf_counter()
            urllib.request.urlopen(urllib.request.Request(url, headers={"accept-encoding": "gzip"})).read()
            latencies.append((time.perf_counter() - start) * 1e3)
        return latencies
    finally:
        server.terminate()
        server.wait()


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--dem", default=str(ROOT / "examples/grids/dem-4326.tif"))
    p.add_argument("--no-build", action="store_true")
    p.add_argument("--processes", type=int, default=os.cpu_count())
    p.add_argument("--window-error", type=float, default=0.9, help="the DEM window's max_error, times the level's")
    p.add_argument("--meshfit", default=str(MESHFIT), help="the binary (default: the release build)")
    args = p.parse_args()
    global WINDOW_ERROR
    WINDOW_ERROR = args.window_error
    if not args.no_build and args.meshfit == str(MESHFIT):
        subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    dem = Dem(args.dem)
    out = Path(tempfile.mkdtemp(prefix="meshfit-tiles-"))
    try:
        start = time.perf_counter()
        subprocess.run([args.meshfit, "tiles", args.dem, "--out", str(out)], check=True, capture_output=True)
        meshfit_time = time.perf_counter() - start
        layer = json.loads((out / "layer.json").read_text())
        ours, wanted = {}, []
        for z, ranges in enumerate(layer["available"]):
            for r in ranges:
                for y in range(r["startY"], r["endY"] + 1):
                    for x in range(r["startX"], r["endX"] + 1):
                        ours[(z, x, y)] = (out / f"{z}/{x}/{y}.terrain").read_bytes()
                        if bounds(z, x, y)[0] < dem.east and bounds(z, x, y)[2] > dem.west:
                            wanted.append((args.dem, z, x, y))
        start = time.perf_counter()
        with Pool(args.processes, initializer=init, initargs=(args.dem,)) as pool:
            theirs = dict(pool.map(delatin_tile, wanted))
        delatin_time = time.perf_counter() - start
        with Pool(args.processes, initializer=init, initargs=(args.dem,)) as pool:
            windows = {k: v for k, v in pool.map(delatin_window, wanted) if v is not None}
        ours = {k: v for k, v in ours.items() if k in theirs}
        levels = range(layer["maxzoom"] + 1)
        print(f"DEM {Path(args.dem).name}: {dem.nx} x {dem.ny}, pixel {dem.sx * 3600:.2f}\", levels 0..{layer['maxzoom']}")
        print(f"time: meshfit tiles {meshfit_time:.2f} s (every core); pydelatin + quantized-mesh-encoder {delatin_time:.2f} s ({args.processes} processes)")
        print()
        print("| pipeline | z | tiles | vertices | in tiles wholly on the DEM | gzip bytes | max error (m) | of the level's | cracked sides | largest gap (m) |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        by_level = [
            measure("meshfit", ours, dem, levels),
            measure("pydelatin", theirs, dem, levels),
            measure("pydelatin, DEM window", windows, dem, levels),
        ]
        key = lambda row: row[1]
        rows_at = [{key(r): r for r in rows} for rows in by_level]
        for z in levels:
            for name, z, n, v, inner, gz, worst, frac, cracked, shared, gap in (r[z] for r in rows_at if z in r):
                print(f"| {name} | {z} | {n} | {v} | {inner} | {gz} | {worst:.2f} | {frac:.2f} | {cracked}/{shared} | {gap:.3f} |")
        deepest = sorted(k[1:] for k in ours if k[0] == layer["maxzoom"])
        zmax = layer["maxzoom"]
        served = on_demand(args.meshfit, args.dem, [(zmax, x, y) for x, y in deepest])
        init(args.dem)
        timed = {}
        for name, make in (("pydelatin", delatin_tile), ("DEM window", delatin_window)):
            times = []
            for x, y in deepest:
                start = time.perf_counter()
                make((args.dem, zmax, x, y))
                times.append((time.perf_counter() - start) * 1e3)
            timed[name] = statistics.median(times)
        print()
        print(
            f"on demand, level {zmax} ({len(deepest)} tiles, uncached): meshfit serve {statistics.median(served):.1f} ms "
            f"median, {max(served):.1f} ms largest (HTTP, gzip included); pydelatin {timed['pydelatin']:.1f} ms, "
            f"DEM window {timed['DEM window']:.1f} ms median (in process)"
        )
    finally:
        shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
