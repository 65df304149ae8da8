#!/usr/bin/env python3
"""meshfit's client jobs (ask/tell over HTTP, criterion curvature) against python-adaptive's
Learner2D at equal evaluations of F, on the functions of docs/quality.md and Learner2D's own
`ring` example.

Run by hand, never in CI (it needs packages from PyPI and takes about half an hour, mostly
Learner2D at 2*10^4 points):

    python3 -m venv bench/.venv
    bench/.venv/bin/pip install numpy scipy matplotlib adaptive ./clients/python
    cargo build --release
    bench/.venv/bin/python bench/asktell.py --sizes 1000 5000 20000

meshfit's evaluations are its vertices plus the points a batch guessed ahead and the mesh
left unused (a few percent); Learner2D's are n. Each run evaluates F one point at a time on one thread, as a simulation too dear to run twice
would be. meshfit: `Client.learn` against the release binary on a loopback port (its
default batch of 16 points a request). Learner2D: `adaptive.runner.simple`, one point a
step, as its docs' examples run it. Both report:

- E_max: max |F - F_n| on the dense sample of bench/compare.py (a 1001 x 1001 lattice plus
  every vertex, edge midpoint and centroid), F_n on the mesh's own triangles (meshfit's; the
  Delaunay triangulation of Learner2D's points, as its interpolator does);
- RMS: over a 501 x 501 lattice, F_n by the same triangulations;
- overhead: the wall time minus the time inside F, per evaluation.
"""

import argparse
import math
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from matplotlib import tri as mtri

sys.path.insert(0, str(Path(__file__).resolve().parent))
from compare import FUNCTIONS, e_max  # noqa: E402  (the quality functions and the dense sample)

MESHFIT = Path(__file__).resolve().parent.parent / "target" / "release" / "meshfit"

RING = (
    "ring",
    None,
    lambda x, y: x + np.exp(-((x ** 2 + y ** 2 - 0.75 ** 2) ** 2) / 0.2 ** 4),
    (-1.0, 1.0, -1.0, 1.0),
)


class Timed:
    """F with the time spent inside it."""

    def __init__(self, f):
        self.f, self.seconds, self.calls = f, 0.0, 0

    def __call__(self, x, y):
        start = time.perf_counter()
        value = float(self.f(x, y))
        self.seconds += time.perf_counter() - start
        self.calls += 1
        return value


def rms(f, domain, x, y, z, triangles, n=501):
    a, b, c, d = domain
    gx, gy = np.meshgrid(np.linspace(a, b, n), np.linspace(c, d, n))
    triangulation = mtri.Triangulation(x, y, triangles)
    approx = mtri.LinearTriInterpolator(triangulation, z)(gx, gy)
    inside = ~np.ma.getmaskarray(approx)
    diff = f(gx[inside], gy[inside]) - np.asarray(approx)[inside]
    return float(np.sqrt(np.mean(diff ** 2)))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server():
    port = free_port()
    # Only our own settings: the server refuses MESHFIT_* variables it does not know.
    env = {k: v for k, v in os.environ.items() if not k.startswith("MESHFIT_")}
    env.update({"MESHFIT_ADDR": f"127.0.0.1:{port}", "MESHFIT_LOG": "warn"})
    server = subprocess.Popen([str(MESHFIT)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    import httpx

    for _ in range(200):
        try:
            httpx.get(url + "/healthz", timeout=1).raise_for_status()
            return server, url
        except httpx.HTTPError:
            time.sleep(0.05)
    server.kill()
    raise SystemExit("the server did not start")


def meshfit_run(client, f, domain, n):
    a, b, c, d = domain
    timed = Timed(f)
    start = time.perf_counter()
    result = client.learn(timed, x=(a, b), y=(c, d), max_vertices=n, progress=False)
    wall = time.perf_counter() - start
    x, y, z = result.vertices[:, 0], result.vertices[:, 1], result.values
    return {
        "e_max": e_max(f, domain, x, y, z, result.triangles),
        "rms": rms(f, domain, x, y, z, result.triangles),
        "evaluations": timed.calls,
        "overhead": (wall - timed.seconds) / timed.calls,
    }


def learner2d_run(f, domain, n):
    import adaptive

    a, b, c, d = domain
    timed = Timed(f)
    learner = adaptive.Learner2D(lambda p: timed(p[0], p[1]), bounds=[(a, b), (c, d)])
    start = time.perf_counter()
    adaptive.runner.simple(learner, npoints_goal=n)
    wall = time.perf_counter() - start
    points = np.array(list(learner.data.keys()))
    values = np.array(list(learner.data.values()))
    triangles = mtri.Triangulation(points[:, 0], points[:, 1]).triangles
    x, y = points[:, 0], points[:, 1]
    return {
        "e_max": e_max(f, domain, x, y, values, triangles),
        "rms": rms(f, domain, x, y, values, triangles),
        "evaluations": timed.calls,
        "overhead": (wall - timed.seconds) / timed.calls,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 5000, 20000])
    parser.add_argument("--functions", nargs="+", help="names to run (default: all)")
    args = parser.parse_args()
    import meshfit

    functions = [fn for fn in FUNCTIONS + [RING] if not args.functions or fn[0] in args.functions]
    server, url = start_server()
    client = meshfit.Client(url)
    ratios, overheads = [], []
    print("| function | n | meshfit's evaluations | E_max meshfit | E_max Learner2D | ratio | RMS meshfit "
          "| RMS Learner2D | overhead meshfit (ms/pt) | overhead Learner2D (ms/pt) | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    try:
        for name, _text, f, domain in functions:
            for n in args.sizes:
                mine, theirs = meshfit_run(client, f, domain, n), learner2d_run(f, domain, n)
                ratio, overhead = mine["e_max"] / theirs["e_max"], mine["overhead"] / theirs["overhead"]
                ratios.append(ratio)
                overheads.append(overhead)
                print(f"| {name} | {n} | {mine['evaluations']} | {mine['e_max']:.2e} | {theirs['e_max']:.2e} | {ratio:.2f} "
                      f"| {mine['rms']:.2e} | {theirs['rms']:.2e} | {1e3 * mine['overhead']:.3f} "
                      f"| {1e3 * theirs['overhead']:.2f} | {overhead:.3f} |", flush=True)
    finally:
        server.terminate()
        server.wait()

    def geometric_mean(values):
        return math.exp(sum(math.log(v) for v in values) / len(values))

    print(f"\nGeometric means: E_max ratio {geometric_mean(ratios):.2f}, overhead ratio "
          f"{geometric_mean(overheads):.3f}")


if __name__ == "__main__":
    main()
