#!/usr/bin/env python3
"""Max error of meshfit against pydelatin (hmm's greedy insertion) and python-adaptive's
Learner2D at equal vertex counts, on the quality functions of the error criterion.

Run by hand, never in CI (it needs packages from PyPI and takes minutes):

    pip install numpy matplotlib pydelatin adaptive
    cargo build --release
    python3 bench/compare.py --sizes 1000 10000 > docs/quality.md

E_max is measured on a dense sample: a 1001 x 1001 grid over the domain plus every vertex,
edge midpoint and centroid of the mesh under test, comparing F with the mesh's piecewise
linear interpolant. pydelatin meshes a 2049 x 2049 raster of F; its error is still measured
against F itself.
"""

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from matplotlib import tri as mtri  # Delaunay triangulation of python-adaptive's points

MESHFIT = Path(__file__).resolve().parent.parent / "target" / "release" / "meshfit"

FUNCTIONS = [
    ("franke",
     "0.75*exp(-((9*x-2)^2 + (9*y-2)^2)/4) + 0.75*exp(-((9*x+1)^2)/49 - (9*y+1)/10)"
     " + 0.5*exp(-((9*x-7)^2 + (9*y-3)^2)/4) - 0.2*exp(-((9*x-4)^2) - (9*y-7)^2)",
     lambda x, y: 0.75 * np.exp(-((9 * x - 2) ** 2 + (9 * y - 2) ** 2) / 4)
     + 0.75 * np.exp(-((9 * x + 1) ** 2) / 49 - (9 * y + 1) / 10)
     + 0.5 * np.exp(-((9 * x - 7) ** 2 + (9 * y - 3) ** 2) / 4)
     - 0.2 * np.exp(-((9 * x - 4) ** 2) - (9 * y - 7) ** 2),
     (0.0, 1.0, 0.0, 1.0)),
    ("peaks",
     "3*(1-x)^2*exp(-x^2 - (y+1)^2) - 10*(x/5 - x^3 - y^5)*exp(-x^2-y^2) - exp(-(x+1)^2 - y^2)/3",
     lambda x, y: 3 * (1 - x) ** 2 * np.exp(-x ** 2 - (y + 1) ** 2)
     - 10 * (x / 5 - x ** 3 - y ** 5) * np.exp(-x ** 2 - y ** 2)
     - np.exp(-(x + 1) ** 2 - y ** 2) / 3,
     (-3.0, 3.0, -3.0, 3.0)),
    ("x^2+y^3", "x^2 + y^3", lambda x, y: x ** 2 + y ** 3, (0.0, 1.0, 0.0, 1.0)),
    ("exp(x+y)", "exp(x+y)", lambda x, y: np.exp(x + y), (0.0, 1.0, 0.0, 1.0)),
    ("bump", "exp(-100*((x-0.4)^2+(y-0.6)^2))",
     lambda x, y: np.exp(-100 * ((x - 0.4) ** 2 + (y - 0.6) ** 2)), (0.0, 1.0, 0.0, 1.0)),
    ("sin*cos", "sin(10*x)*cos(10*y)", lambda x, y: np.sin(10 * x) * np.cos(10 * y), (0.0, 1.0, 0.0, 1.0)),
    ("tanh front", "tanh(40*(x+y-1))", lambda x, y: np.tanh(40 * (x + y - 1)), (0.0, 1.0, 0.0, 1.0)),
]


def e_max(f, domain, x, y, z, triangles):
    """max |F - F_n| over the dense sample of the triangulation (x, y, z, triangles)."""
    a, b, c, d = domain
    t = np.asarray(triangles)
    # Vertices, edge midpoints and centroids: F_n there is the mean of the corner values.
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    px = np.concatenate([x, x[edges].mean(axis=1), x[t].mean(axis=1)])
    py = np.concatenate([y, y[edges].mean(axis=1), y[t].mean(axis=1)])
    pz = np.concatenate([z, z[edges].mean(axis=1), z[t].mean(axis=1)])
    # Clamp rounding just outside the rectangle back onto it.
    worst = float(np.max(np.abs(f(np.clip(px, a, b), np.clip(py, c, d)) - pz)))
    return max(worst, grid_error_by_triangle(f, domain, x, y, z, t))


def grid_error_by_triangle(f, domain, x, y, z, t, n=1001):
    """max |F - F_n| over the n x n grid points, found per triangle from its bounding box.

    Not matplotlib's point locator: on meshes with very thin triangles (the paper's recursive
    meshes) it fails or puts points in the wrong triangle."""
    a, b, c, d = domain
    xs, ys = np.linspace(a, b, n), np.linspace(c, d, n)
    worst = 0.0
    covered = np.zeros((n, n), dtype=bool)
    for i, j, k in t:
        tx, ty = x[[i, j, k]], y[[i, j, k]]
        c0, c1 = np.searchsorted(xs, tx.min()), np.searchsorted(xs, tx.max(), side="right")
        r0, r1 = np.searchsorted(ys, ty.min()), np.searchsorted(ys, ty.max(), side="right")
        gx, gy = np.meshgrid(xs[c0:c1], ys[r0:r1])
        det = (tx[1] - tx[0]) * (ty[2] - ty[0]) - (ty[1] - ty[0]) * (tx[2] - tx[0])
        if det == 0:  # flat in floating point: its points are its neighbours' too
            continue
        wb = ((gx - tx[0]) * (ty[2] - ty[0]) - (gy - ty[0]) * (tx[2] - tx[0])) / det
        wc = ((tx[1] - tx[0]) * (gy - ty[0]) - (ty[1] - ty[0]) * (gx - tx[0])) / det
        wa = 1 - wb - wc
        inside = (wa >= -1e-12) & (wb >= -1e-12) & (wc >= -1e-12)
        if inside.any():
            # Rounding in a thin triangle can push a weight past [0, 1]: clip, so F_n never
            # extrapolates.
            w = np.clip(np.stack([wa[inside], wb[inside], wc[inside]]), 0.0, None)
            approx = (w[0] * z[i] + w[1] * z[j] + w[2] * z[k]) / w.sum(axis=0)
            worst = max(worst, float(np.max(np.abs(f(gx[inside], gy[inside]) - approx))))
            covered[r0:r1, c0:c1] |= inside
    if not covered.all():
        print(f"warning: {np.count_nonzero(~covered)} grid points in no triangle", file=sys.stderr)
    return worst


def meshfit(name, text, f, domain, n, criterion, method):
    a, b, c, d = domain
    start = time.perf_counter()
    out = subprocess.run(
        [str(MESHFIT), "mesh", "--function", text, f"--domain={a},{b},{c},{d}", "--max-vertices", str(n),
         "--criterion", criterion, "--method", method],
        check=True, capture_output=True).stdout
    seconds = time.perf_counter() - start
    doc = json.loads(out)
    v = np.asarray(doc["vertices"])
    return e_max(f, domain, v[:, 0], v[:, 1], v[:, 2], doc["triangles"]), len(v), seconds


def pydelatin(name, text, f, domain, n, raster=2049):
    from pydelatin import Delatin
    a, b, c, d = domain
    xs, ys = np.linspace(a, b, raster), np.linspace(c, d, raster)
    gx, gy = np.meshgrid(xs, ys)
    heights = f(gx, gy).astype(np.float32)
    start = time.perf_counter()
    tin = Delatin(heights, max_points=n, max_error=0.0)
    seconds = time.perf_counter() - start
    v = np.asarray(tin.vertices, dtype=float)
    # pydelatin counts its y from the last row up.
    col, row = v[:, 0].round().astype(int), (raster - 1 - v[:, 1]).round().astype(int)
    x = a + col / (raster - 1) * (b - a)
    y = c + row / (raster - 1) * (d - c)
    z = heights[row, col].astype(float)
    return e_max(f, domain, x, y, z, tin.triangles), len(v), seconds


def learner2d(name, text, f, domain, n):
    import adaptive
    a, b, c, d = domain
    learner = adaptive.Learner2D(lambda p: float(f(p[0], p[1])), bounds=[(a, b), (c, d)])
    start = time.perf_counter()
    adaptive.runner.simple(learner, npoints_goal=n)
    seconds = time.perf_counter() - start
    points = np.array(list(learner.data.keys()))
    values = np.array(list(learner.data.values()))
    triangulation = mtri.Triangulation(points[:, 0], points[:, 1])
    return e_max(f, domain, points[:, 0], points[:, 1], values, triangulation.triangles), len(points), seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    parser.add_argument("--skip-adaptive", action="store_true", help="python-adaptive is slow at 10^4 points")
    args = parser.parse_args()
    tools = [
        ("meshfit error semi", lambda *a: meshfit(*a, "error", "semi-recursive")),
        ("meshfit error recursive", lambda *a: meshfit(*a, "error", "recursive")),
        ("meshfit variation semi", lambda *a: meshfit(*a, "variation", "semi-recursive")),
        ("meshfit variation recursive", lambda *a: meshfit(*a, "variation", "recursive")),
        ("pydelatin", pydelatin),
    ]
    if not args.skip_adaptive:
        tools.append(("adaptive Learner2D", learner2d))
    print("| function | n | " + " | ".join(name for name, _ in tools) + " |")
    print("|---|---|" + "---|" * len(tools))
    for name, text, f, domain in FUNCTIONS:
        for n in args.sizes:
            cells = []
            for tool, run in tools:
                err, vertices, seconds = run(name, text, f, domain, n)
                cells.append(f"{err:.2e}" + ("" if vertices == n else f" ({vertices} v)"))
                print(f"{name} n={n} {tool}: E_max {err:.3e}, {vertices} vertices, {seconds:.2f} s", file=sys.stderr)
            print(f"| {name} | {n} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
