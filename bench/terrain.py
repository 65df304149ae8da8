#!/usr/bin/env python3
"""meshfit against pydelatin (hmm's greedy insertion) on real elevation data, measured as a
heightmap user measures: the same vertex count, the max and RMS error at every pixel, and the
engine's time.

Run by hand, never in CI (it builds the release binary and takes a few minutes):

    python3 -m venv bench/.venv && bench/.venv/bin/pip install numpy matplotlib pillow pydelatin
    bench/.venv/bin/python bench/terrain.py              # the table on stdout, for docs/terrain.md
    bench/.venv/bin/python bench/terrain.py --no-build --runs 1 --sizes 10000
    bench/.venv/bin/python bench/terrain.py --before old/meshfit   # an earlier build beside

DEMs: the two elevation rasters of matplotlib's sample data (jacksboro_fault_dem.npz, 344 x 403
SRTM-derived metres; topobathy.npz, 91 x 120), each also as a web-map tile in both colour
encodings (Terrain-RGB and Terrarium PNG, made here from the raster; the heights the tile holds
are the decoded ones, so both tools mesh the same numbers), and any .npy, single-band GeoTIFF or
colour tile given with --dem (meshfit reads the file itself, pydelatin its decoded heights):

    bench/.venv/bin/python bench/terrain.py --dem dem.tif fuji.png:terrain-rgb

A budget is measured only where it is at most half the pixels. Each of meshfit's --methods
(semi-recursive and data-dependent by default) is a row beside pydelatin.

E_max and RMS come from one function for both meshes: F_n is interpolated linearly over the
mesh's triangles at every pixel (matplotlib's triangle finder) and compared with the pixel's
height. Time is the engine's: meshfit's `elapsed_ms` of `--stats` (the refinement, without
reading the file), pydelatin's constructor (copying the raster in, then refining). The tools run
alternately, `--runs` times each; times are medians.
"""

import argparse
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from matplotlib import cbook
from matplotlib.tri import LinearTriInterpolator, Triangulation

ROOT = Path(__file__).resolve().parent.parent
MESHFIT = ROOT / "target" / "release" / "meshfit"


def sample_dem(name, key):
    with cbook.get_sample_data(name) as data:
        return np.asarray(data[key], dtype=np.float64)


def terrain_rgb(heights):
    """(RGB bytes, decoded heights): height = -10000 + (R*65536 + G*256 + B) * 0.1."""
    code = np.round((heights + 10000.0) * 10.0).astype(np.int64)
    rgb = np.stack([(code >> 16) & 255, (code >> 8) & 255, code & 255], axis=-1).astype(np.uint8)
    return rgb, -10000.0 + (code.astype(np.float64)) * 0.1


def terrarium(heights):
    """(RGB bytes, decoded heights): height = R*256 + G + B/256 - 32768."""
    code = np.round((heights + 32768.0) * 256.0).astype(np.int64)
    rgb = np.stack([(code >> 16) & 255, (code >> 8) & 255, code & 255], axis=-1).astype(np.uint8)
    return rgb, code.astype(np.float64) / 256.0 - 32768.0


def dems(args, tmp):
    """(name, heights as float64 (rows, cols), meshfit's source arguments, the same heights as
    .npy arguments for an earlier build that may not read tiles) for every DEM."""
    from PIL import Image
    out = []
    for label, name, key in [("jacksboro", "jacksboro_fault_dem.npz", "elevation"),
                             ("topobathy", "topobathy.npz", "topo")]:
        try:
            heights = sample_dem(name, key)
        except (OSError, KeyError) as e:
            print(f"skipping {name}: {e}", file=sys.stderr)
            continue
        path = Path(tmp) / f"{label}.npy"
        np.save(path, heights)
        out.append((f"{label} (npy)", heights, ["--grid", str(path)], ["--grid", str(path)]))
        for encoding, encode in [("terrain-rgb", terrain_rgb), ("terrarium", terrarium)]:
            rgb, decoded = encode(heights)
            png = Path(tmp) / f"{label}-{encoding}.png"
            Image.fromarray(rgb, "RGB").save(png)
            plain = Path(tmp) / f"{label}-{encoding}.npy"
            np.save(plain, decoded)
            out.append((f"{label} ({encoding})", decoded, ["--grid", str(png), "--encoding", encoding],
                        ["--grid", str(plain)]))
    for spec in args.dem:
        path, _, encoding = str(spec).partition(":")
        path = Path(path)
        if path.suffix == ".npy":
            heights = np.load(path).astype(np.float64)
        elif encoding:
            rgb = np.asarray(Image.open(path).convert("RGB")).astype(np.int64)
            code = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
            heights = (-10000.0 + code * 0.1 if encoding == "terrain-rgb"
                       else (code.astype(np.float64) / 256.0 - 32768.0))
        else:  # a single-band GeoTIFF, or any image PIL reads as one band
            heights = np.asarray(Image.open(path)).astype(np.float64)
        plain = Path(tmp) / f"{path.stem}.npy"
        np.save(plain, heights)
        rows, cols = heights.shape
        # Pixel units, whatever a GeoTIFF's own georeferencing says, as pixel_errors measures.
        source = ["--grid", str(path), "--domain", f"0,{cols - 1},0,{rows - 1}"]
        source += ["--encoding", encoding] if encoding else []
        out.append((f"{path.stem}{f' ({encoding})' if encoding else ''}", heights, source, ["--grid", str(plain)]))
    return out


def pixel_errors(heights, xs, ys, zs, triangles):
    """(E_max, RMS) of the mesh against every pixel: F_n by linear interpolation over the
    triangles, vertices in pixel units. Both tools read an image's first row as its north edge,
    at y = rows - 1: x is the column, y = rows - 1 - row."""
    rows, cols = heights.shape
    heights = heights[::-1]
    tri = Triangulation(xs, ys, triangles)
    gx, gy = np.meshgrid(np.arange(cols, dtype=np.float64), np.arange(rows, dtype=np.float64))
    approx = LinearTriInterpolator(tri, zs)(gx, gy)
    if np.ma.is_masked(approx) and approx.mask.any():
        raise SystemExit(f"{approx.mask.sum()} pixels fall outside the mesh")
    diff = np.asarray(approx) - heights
    return float(np.abs(diff).max()), float(np.sqrt(np.mean(diff * diff)))


def meshfit_time(binary, source, n, method=None):
    method = ["--method", method] if method else []
    out = subprocess.run([str(binary), "mesh", *source, "--max-vertices", str(n), *method, "--stats"],
                         check=True, capture_output=True).stdout
    doc = json.loads(out)
    return doc["elapsed_ms"], doc["stats"]["vertices"]


def meshfit_mesh(binary, source, n, method=None):
    method = ["--method", method] if method else []
    out = subprocess.run([str(binary), "mesh", *source, "--max-vertices", str(n), *method],
                         check=True, capture_output=True).stdout
    doc = json.loads(out)
    v = np.asarray(doc["vertices"], dtype=np.float64)
    return v[:, 0], v[:, 1], v[:, 2], np.asarray(doc["triangles"], dtype=np.int64)


def pydelatin_run(heights32, n):
    from pydelatin import Delatin
    start = time.perf_counter()
    tin = Delatin(heights32, max_points=n, max_error=0.0)
    ms = (time.perf_counter() - start) * 1e3
    return ms, tin


def geomean(values):
    return math.exp(sum(math.log(v) for v in values) / len(values))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5, help="timed runs per tool and case (medians)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1_000, 10_000, 50_000, 100_000])
    parser.add_argument("--dem", nargs="*", default=[], metavar="FILE[:ENCODING]",
                        help="more DEMs: .npy (rows, cols), a single-band GeoTIFF, or a colour tile with "
                             "its encoding (tile.png:terrain-rgb, tile.png:terrarium)")
    parser.add_argument("--methods", nargs="+", default=["semi-recursive", "data-dependent"],
                        help="meshfit's methods, each a row beside pydelatin")
    parser.add_argument("--no-build", action="store_true", help="use target/release/meshfit as it is")
    parser.add_argument("--before", type=Path, metavar="BINARY", help="an earlier meshfit build, run alternately")
    args = parser.parse_args()
    if not args.no_build:
        subprocess.run(["cargo", "build", "--release"], cwd=ROOT, check=True)
    # (label, binary, method, whether it reads tiles): each meshfit method, then the earlier build
    # with its default method on the decoded heights.
    tools = [(m, MESHFIT, m, True) for m in args.methods]
    tools += [("before", args.before, None, False)] if args.before else []

    rows, ratios = [], {}
    with tempfile.TemporaryDirectory(prefix="meshfit-terrain-") as tmp:
        for name, heights, source, plain in dems(args, tmp):
            ny, nx = heights.shape
            # pydelatin's binding takes float32; the sample DEMs and the decoded tiles are
            # integers or multiples of 0.1 and 1/256 below 2^14, so both see the same values
            # up to float32's rounding of 0.1 steps (under 1e-4 m).
            heights32 = heights.astype(np.float32)
            for n in args.sizes:
                if n > nx * ny // 2:
                    continue
                times = {label: [] for label, *_ in tools}
                times["pydelatin"] = []
                for _ in range(args.runs):  # alternate, so drift in the machine's speed hits all
                    for label, binary, method, tiles in tools:
                        times[label].append(meshfit_time(binary, source if tiles else plain, n, method)[0])
                    times["pydelatin"].append(pydelatin_run(heights32, n)[0])
                _, tin = pydelatin_run(heights32, n)
                hv, ht = np.asarray(tin.vertices, dtype=np.float64), np.asarray(tin.triangles, dtype=np.int64)
                h = (len(hv), *pixel_errors(heights, hv[:, 0], hv[:, 1], hv[:, 2], ht),
                     statistics.median(times["pydelatin"]))
                results = {}
                for label, binary, method, tiles in tools:
                    xs, ys, zs, tris = meshfit_mesh(binary, source if tiles else plain, n, method)
                    results[label] = (len(xs), *pixel_errors(heights, xs, ys, zs, tris),
                                      statistics.median(times[label]))
                before = ""
                if args.before:
                    b = results["before"]
                    before = f" {b[1]:.3f} | {b[1] / h[1]:.3f} | {b[3]:.1f} |"
                for method in args.methods:
                    m = results[method]
                    ratios.setdefault((method, n), []).append((m[1] / h[1], m[3] / h[3]))
                    rows.append(f"| {name} | {nx}x{ny} | {n} | {method} | {m[0]} | {h[0]} | {m[1]:.3f} |"
                                f" {h[1]:.3f} | {m[1] / h[1]:.3f} | {m[2]:.3f} | {h[2]:.3f} | {m[3]:.1f} |"
                                f" {h[3]:.1f} | {m[3] / h[3]:.2f} |{before}")
                    print(rows[-1], file=sys.stderr, flush=True)

    extra = " E_max before | before / hmm | before ms |" if args.before else ""
    print(f"{args.runs} timed run(s) per tool and case, medians; E_max and RMS at every pixel\n")
    print("| DEM | pixels | n | method | vertices meshfit | vertices hmm | E_max meshfit | E_max hmm"
          f" | E_max ratio | RMS meshfit | RMS hmm | ms meshfit | ms hmm | time ratio |{extra}")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|" + ("---|---|---|" if args.before else ""))
    print("\n".join(rows))
    print("\n| method | n | E_max ratio, geometric mean | E_max ratio, max | time ratio, geometric mean"
          " | time ratio, max |")
    print("|---|---|---|---|---|---|")
    for (method, n), rs in sorted(ratios.items()):
        e, t = [r[0] for r in rs], [r[1] for r in rs]
        print(f"| {method} | {n} | {geomean(e):.3f} | {max(e):.3f} | {geomean(t):.2f} | {max(t):.2f} |")


if __name__ == "__main__":
    main()
