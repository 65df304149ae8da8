#!/usr/bin/env python3
"""Refinement time of meshfit against pydelatin (hmm's greedy insertion) on the same grids, and
meshfit's time on Franke's expression against its targets.

Run by hand, never in CI (it builds the release binary and takes minutes):

    pip install numpy matplotlib pydelatin
    python3 bench/speed.py                        # tables on stdout, for docs/speed.md
    python3 bench/speed.py --no-build --quick     # smoke test: 1025 grid and DEM, 10^4, 1 run
    python3 bench/speed.py --before old/meshfit   # also an earlier build, alternately, on the grids
                                                  # and in the engine table
    python3 bench/speed.py --no-build --only engine   # just issue #24's table (a few minutes)

Grids: Franke's function sampled at 1025 x 1025 and 4097 x 4097 on [0,1]^2, and the two
elevation rasters of matplotlib's sample data (jacksboro_fault_dem.npz, topobathy.npz). Each is
written as a float64 .npy file for `meshfit mesh --grid`. meshfit's time is the `elapsed_ms` of
`--stats`: the refinement alone, without reading the file or estimating the error. pydelatin's
time is its constructor (copying the raster in, then refining). The tools run alternately,
`--runs` times each, and the tables give medians. E_max is the max error at the grid nodes.

The engine table (issue #24) measures every row against one yardstick, pydelatin meshing the
1025 x 1025 Franke grid to 10^5 vertices, run alternately with the rows: the paper's variation
criterion at 10^6, the error criterion through meval at 10^5, `meshfit solve` of the
exp(-1000 r^2) peak to 10^5 vertices (the whole process, wall clock), and peak memory at 10^6
(maximum resident set of the process, less that of a 4-vertex run, per vertex).
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from matplotlib import cbook

ROOT = Path(__file__).resolve().parent.parent
MESHFIT = ROOT / "target" / "release" / "meshfit"
METHODS = ["semi-recursive", "recursive"]

# Copied from benches/support/franke.rs (meval syntax: ^ is a power).
FRANKE = ("0.75*exp(-((9*x-2)^2 + (9*y-2)^2)/4) + 0.75*exp(-((9*x+1)^2)/49 - (9*y+1)/10)"
          " + 0.5*exp(-((9*x-7)^2 + (9*y-3)^2)/4) - 0.2*exp(-((9*x-4)^2) - (9*y-7)^2)")

# (criterion, method, n, target ms) for meshfit on the FRANKE expression over [0,1]^2.
EXPRESSION_CASES = [
    ("error", "semi-recursive", 100_000, 100),
    ("variation", "semi-recursive", 100_000, 40),
    ("variation", "semi-recursive", 1_000_000, 1000),
    ("variation", "recursive", 1_000_000, 400),
]


def franke(x, y):
    return (0.75 * np.exp(-((9 * x - 2) ** 2 + (9 * y - 2) ** 2) / 4)
            + 0.75 * np.exp(-((9 * x + 1) ** 2) / 49 - (9 * y + 1) / 10)
            + 0.5 * np.exp(-((9 * x - 7) ** 2 + (9 * y - 3) ** 2) / 4)
            - 0.2 * np.exp(-((9 * x - 4) ** 2) - (9 * y - 7) ** 2))


def franke_grid(size):
    """Franke's function on a size x size grid over [0,1]^2, shape (ny, nx): row j is y_j."""
    xs = np.linspace(0.0, 1.0, size)
    gx, gy = np.meshgrid(xs, xs)
    return franke(gx, gy)


def sample_grid(name, key):
    """An elevation array from matplotlib's sample data as float64, or None if it is absent."""
    try:
        with cbook.get_sample_data(name) as data:
            return np.asarray(data[key], dtype=np.float64)
    except (OSError, KeyError) as e:
        print(f"skipping {name}: {e}", file=sys.stderr)
        return None


def grids(args):
    """(name, loader) pairs; loaders run one at a time so only one big grid is in memory."""
    out = [("franke 1025", lambda: franke_grid(1025))]
    if not (args.quick or args.skip_4097):
        out.append(("franke 4097", lambda: franke_grid(4097)))
    out.append(("jacksboro DEM", lambda: sample_grid("jacksboro_fault_dem.npz", "elevation")))
    if not args.quick:
        out.append(("topobathy", lambda: sample_grid("topobathy.npz", "topo")))
    return out


def run_meshfit(source, n, method, criterion="error", binary=MESHFIT):
    """(elapsed_ms, vertices, max_error) from `meshfit mesh ... --stats`; source is CLI args."""
    out = subprocess.run(
        [str(binary), "mesh", *source, "--max-vertices", str(n), "--method", method,
         "--criterion", criterion, "--stats"],
        check=True, capture_output=True).stdout
    doc = json.loads(out)
    return doc["elapsed_ms"], doc["stats"]["vertices"], doc["error"]["max_error"]


def run_pydelatin(heights, n):
    """(ms, vertices, max_error) for pydelatin stopping on the point budget n.

    max_error=0 so only max_points stops it (its default max_error=0.001 would stop early).
    tin.error is hmm's max error over every raster pixel, i.e. at the grid nodes, so it is free.
    """
    from pydelatin import Delatin
    start = time.perf_counter()
    tin = Delatin(heights, max_points=n, max_error=0.0)
    ms = (time.perf_counter() - start) * 1e3
    return ms, len(tin.vertices), float(tin.error)


def ratio(ms, reference_ms):
    r = ms / reference_ms
    return f"{r:.2f}x slower" if r >= 1 else f"{1 / r:.2f}x faster"


def median_of(runs):
    """Medians of the time and the last run's vertices and error (those are deterministic)."""
    return statistics.median(r[0] for r in runs), runs[-1][1], runs[-1][2]


def bench_grids(args, tmp):
    """Returns (time rows, check rows, before/after rows) for the Markdown tables."""
    times, checks, befores = [], [], []
    for name, load in grids(args):
        values = load()
        if values is None:
            continue
        ny, nx = values.shape
        path = Path(tmp) / (name.replace(" ", "_") + ".npy")
        np.save(path, values)
        # pydelatin's binding takes float32 only (it would convert float64 itself, inside the
        # timed constructor): it gets the same values, rounded once here. The DEMs (int16,
        # float32) are exact in float32; Franke's values move by ~1e-8 relative.
        heights = values.astype(np.float32)
        del values
        for n in args.sizes:
            if n >= nx * ny:
                print(f"skipping {name} at n={n}: the grid has only {nx * ny} nodes", file=sys.stderr)
                continue
            results = {m: [] for m in [*METHODS, "pydelatin"]}
            if args.before:
                results.update({f"before {m}": [] for m in METHODS})
            for run in range(args.runs):  # alternate, so drift in the machine's speed hits all
                for method in METHODS:
                    results[method].append(run_meshfit(["--grid", str(path)], n, method))
                    if args.before:
                        results[f"before {method}"].append(
                            run_meshfit(["--grid", str(path)], n, method, binary=args.before))
                results["pydelatin"].append(run_pydelatin(heights, n))
                for tool, rs in results.items():
                    ms, v, err = rs[-1]
                    print(f"{name} {nx}x{ny} n={n} run {run + 1} {tool}: {ms:.1f} ms, {v} vertices,"
                          f" E_max {err:.3e}", file=sys.stderr)
            semi, rec, pyd = (median_of(results[t]) for t in [*METHODS, "pydelatin"])
            times.append(f"| {name} | {n} | {semi[0]:.1f} | {rec[0]:.1f} | {pyd[0]:.1f} |"
                         f" {ratio(semi[0], pyd[0])} | {ratio(rec[0], pyd[0])} |")
            checks.append(f"| {name} | {nx}x{ny} | {n} | {semi[1]} | {rec[1]} | {pyd[1]} |"
                          f" {semi[2]:.3e} | {rec[2]:.3e} | {pyd[2]:.3e} |")
            if args.before:
                old_semi, old_rec = (median_of(results[f"before {m}"]) for m in METHODS)
                same = "yes" if (old_semi[1:], old_rec[1:]) == (semi[1:], rec[1:]) else "NO"
                befores.append(f"| {name} | {n} | {old_semi[0]:.1f} | {semi[0]:.1f} | {old_rec[0]:.1f} |"
                               f" {rec[0]:.1f} | {old_semi[0] / semi[0]:.2f}x | {old_rec[0] / rec[0]:.2f}x |"
                               f" {same} |")
    return times, checks, befores


def bench_expressions(args):
    rows = []
    for criterion, method, n, target in EXPRESSION_CASES:
        if args.quick and n > 100_000:
            continue
        runs = [run_meshfit(["--function", FRANKE], n, method, criterion) for _ in range(args.runs)]
        for ms, v, err in runs:
            print(f"franke expression {criterion} {method} n={n}: {ms:.1f} ms, {v} vertices,"
                  f" E_n estimate {err:.3e}", file=sys.stderr)
        ms, v, err = median_of(runs)
        verdict = "met" if ms <= target else "missed"
        rows.append(f"| {criterion} | {method} | {n} | {v} | {ms:.1f} | {target} | {verdict} |")
    return rows


# Issue #24's rows: (label, `meshfit mesh` flags for Franke's expression, target ratio to the
# yardstick); the solve row runs PEAK, the exp(-1000 r^2) problem of bench/solve.py.
PEAK_R2 = "((x-0.5)^2+(y-0.5)^2)"
PEAK = {"physics": "poisson", "domain": {"x": [0, 1], "y": [0, 1]}, "k": "1",
        "f": f"(4000-4000000*{PEAK_R2})*exp(-1000*{PEAK_R2})", "g": f"exp(-1000*{PEAK_R2})",
        "max_vertices": 100_000}
ENGINE_CASES = [
    ("`variation`, semi-recursive, 10^6 (an expression)", ["--criterion", "variation", "--method", "semi-recursive",
                                                         "--max-vertices", "1000000"], 5.0),
    ("`variation`, recursive, 10^6", ["--criterion", "variation", "--method", "recursive",
                                      "--max-vertices", "1000000"], 1.7),
    ("`error`, semi-recursive, Franke through meval, 10^5", ["--criterion", "error", "--method", "semi-recursive",
                                                             "--max-vertices", "100000"], 0.6),
]
SOLVE_LABEL = "`meshfit solve` of the exp(−1000 r²) peak to 10^5 vertices, whole process"
# (criterion, target bytes per vertex) for the memory row, Franke through meval at 10^6.
MEMORY_CASES = [("variation", 170), ("error", 220)]


def run_measured(argv):
    """(wall seconds, stdout) of one process."""
    start = time.perf_counter()
    out = subprocess.run(argv, check=True, capture_output=True).stdout
    return time.perf_counter() - start, out


def peak_rss_kib(argv, tmp):
    """The maximum resident set of a process, by GNU time: a child's own rusage would count the
    Python image it was forked from."""
    report = Path(tmp) / "rss"
    subprocess.run(["/usr/bin/time", "-f", "%M", "-o", str(report), *argv], check=True, capture_output=True)
    return int(report.read_text().split()[-1])


def bench_engine(args, tmp):
    """Rows of issue #24's table: each case's median against the yardstick's median, for this
    build and, with --before, the earlier one, all run alternately."""
    heights = franke_grid(1025).astype(np.float32)
    peak = Path(tmp) / "peak.json"
    peak.write_text(json.dumps(PEAK))
    builds = [("after", MESHFIT), *([("before", args.before)] if args.before else [])]
    labels = [label for label, _, _ in ENGINE_CASES] + [SOLVE_LABEL]
    ms = {(build, label): [] for build, _ in builds for label in labels}
    yardstick = []
    for run in range(args.runs):  # alternate, so drift in the machine's speed hits all
        yardstick.append(run_pydelatin(heights, 100_000)[0])
        for build, binary in builds:
            for label, flags, _ in ENGINE_CASES:
                _, out = run_measured([str(binary), "mesh", "--function", FRANKE, "--stats", *flags])
                ms[build, label].append(json.loads(out)["elapsed_ms"])
            seconds, _ = run_measured([str(binary), "solve", str(peak), "-o", "/dev/null", "--format", "json"])
            ms[build, SOLVE_LABEL].append(seconds * 1e3)
        print(f"engine run {run + 1}: yardstick {yardstick[-1]:.1f} ms, "
              + ", ".join(f"{build} {label}: {v[-1]:.1f}" for (build, label), v in ms.items()), file=sys.stderr)
    reference = statistics.median(yardstick)
    rows = [f"| yardstick: pydelatin, 1025² Franke grid, 10^5 |" + f" {reference:.1f} ms | 1 |" * len(builds) + " |"]
    targets = [target for _, _, target in ENGINE_CASES] + [4.0]
    for label, target in zip(labels, targets):
        cells = "".join(f" {statistics.median(ms[b, label]):.1f} ms | {statistics.median(ms[b, label]) / reference:.2f}× |"
                        for b, _ in builds)
        rows.append(f"| {label} |{cells} ≤ {target}× |")
    # Memory is deterministic enough for one run each.
    cells = ""
    for _, binary in builds:
        base = peak_rss_kib([str(binary), "mesh", "--function", FRANKE, "--max-vertices", "4",
                             "-o", "/dev/null", "--format", "ply"], tmp)
        per_vertex = []
        for criterion, _ in MEMORY_CASES:
            rss = peak_rss_kib([str(binary), "mesh", "--function", FRANKE, "--max-vertices", "1000000",
                                "--criterion", criterion, "-o", "/dev/null", "--format", "ply"], tmp)
            per_vertex.append(f"{(rss - base) * 1024 / 1e6:.1f}")
        cells += f" {' / '.join(per_vertex)} B per vertex | |"
    rows.append(f"| peak memory at 10^6, `variation` / `error` |{cells} "
                + " / ".join(f"≤ {t}" for _, t in MEMORY_CASES) + " |")
    header = "| work |" + "".join(f" {b} | {b} / yardstick |" for b, _ in builds) + " target |"
    return [header, "|---|" + "---|---|" * len(builds) + "---|", *rows]


def command_output(argv):
    try:
        return subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def machine():
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        cpu = platform.processor() or cpu
    from pydelatin import __version__ as pydelatin_version
    rev = command_output(["git", "rev-parse", "HEAD"])
    if command_output(["git", "status", "--porcelain", "--untracked-files=no"]):
        rev += " (with uncommitted changes)"
    return [f"- machine: {os.cpu_count()} CPUs (nproc {command_output(['nproc'])}), {cpu}",
            f"- {command_output([str(MESHFIT), '--version'])}, commit {rev}",
            f"- pydelatin {pydelatin_version}, numpy {np.__version__}, Python {platform.python_version()}"]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3, help="runs per tool and case; the tables give medians")
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000], help="vertex budgets on the grids")
    parser.add_argument("--no-build", action="store_true", help="use target/release/meshfit as it is")
    parser.add_argument("--quick", action="store_true",
                        help="smoke test: the 1025 grid and the DEM at 10^4, expressions at 10^5 only, 1 run")
    parser.add_argument("--skip-4097", action="store_true", help="leave out the 4097 x 4097 Franke grid")
    parser.add_argument("--only", choices=["grids", "expressions", "engine"],
                        help="run one part: the grids against pydelatin, Franke's expression, or #24's table")
    parser.add_argument("--before", type=Path, metavar="BINARY",
                        help="an earlier meshfit build to run alternately on the grids and the engine table")
    args = parser.parse_args()
    if args.quick:
        args.runs, args.sizes = 1, [10_000]
    if not args.no_build:
        subprocess.run(["cargo", "build", "--release"], cwd=ROOT, check=True)

    print("\n".join(machine()) + f"\n- {args.runs} run(s) per case, medians\n")
    if args.only in (None, "grids"):
        with tempfile.TemporaryDirectory(prefix="meshfit-speed-") as tmp:
            times, checks, befores = bench_grids(args, tmp)
        print_grids(args, times, checks, befores)
    if args.only in (None, "expressions"):
        rows = bench_expressions(args)
        print("\n## Franke's expression on [0,1]^2 (meshfit)\n")
        print("| criterion | method | n | vertices | median (ms) | target (ms) | target |")
        print("|---|---|---|---|---|---|---|")
        print("\n".join(rows), flush=True)
    if args.only in (None, "engine") and not args.quick:
        with tempfile.TemporaryDirectory(prefix="meshfit-engine-") as tmp:
            rows = bench_engine(args, tmp)
        print("\n## The engine against one yardstick (issue #24)\n")
        print("\n".join(rows))


def print_grids(args, times, checks, befores):
    print("## Grids: refinement time, criterion error\n")
    print("| grid | n | meshfit semi (ms) | meshfit recursive (ms) | pydelatin (ms) | semi/pydelatin"
          " | recursive/pydelatin |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(times))
    print("\n## Grids: vertices reached and E_max at the grid nodes\n")
    print("| grid | size | n | vertices semi | vertices recursive | vertices pydelatin | E_max semi"
          " | E_max recursive | E_max pydelatin |")
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(checks), flush=True)
    if befores:
        print(f"\n## Grids: {args.before} (before) against this build (after), run alternately\n")
        print("| grid | n | semi before (ms) | semi after (ms) | recursive before (ms) | recursive after (ms)"
              " | semi speed-up | recursive speed-up | same vertices and E_max |")
        print("|---|---|---|---|---|---|---|---|---|")
        print("\n".join(befores), flush=True)


if __name__ == "__main__":
    main()
