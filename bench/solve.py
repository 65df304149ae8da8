#!/usr/bin/env python3
"""meshfit's adaptive P1 solver against scikit-fem's adaptive loop, at equal vertex counts N.

Run by hand, never in CI (it needs packages from PyPI and takes minutes):

    python3 -m venv bench/.venv
    bench/.venv/bin/pip install scikit-fem numpy scipy matplotlib meshio
    bench/.venv/bin/python bench/solve.py [--meshfit target/release/meshfit] [--max-n 20000]

It prints markdown (for docs/solve.md) and saves a log-log plot to bench/out/solve.png.

Problems, -div(k grad u) = f in the unit square, u = g on its boundary:
- smooth: u = sin(pi x) sin(pi y), f = 2 pi^2 u, g = 0, k = 1.
- corner: u = r^(2/3) sin(2 theta/3) about (0, 0), f = 0, g = u, k = 1 (grad u ~ r^(-1/3)).
- peak: u = exp(-a r^2) about (1/2, 1/2), a = 1000; f = -lap u = u (4a - 4a^2 r^2), g = u.
- magnet: A = 0 on the boundary, k = 1/mu0, f = J = 1e6 in [0.2,0.4]x[0.3,0.7], 0 elsewhere.
  No closed form: with A = sum c_mn sin(m pi x) sin(n pi y), -lap A = mu0 f gives
  c_mn = mu0 J_mn / (pi^2 (m^2+n^2)), J_mn = 4 J X_m Y_n, X_m = int_x0^x1 sin(m pi x) dx, so
  W = 1/2 int k |grad A|^2 = 1/8 sum J_mn c_mn = sum mu0 J_mn^2 / (8 pi^2 (m^2+n^2)).
  The error is |W - W_h| / W and the energy-norm error sqrt((W - W_h) / W).

scikit-fem follows its docs example ex22: ElementTriP1 on MeshTri (a 6 x 6 tensor grid, 36
vertices, to start), solve, the residual estimator eta_T^2 = h_T^2 ||f/k||_T^2 + 1/2 sum_E
h_E ||[grad u_h . n]||_E^2 (h_T = sqrt(2 |T|), h_E the edge length; times k for the energy
norm), adaptive_theta (eta_T > theta max eta) and MeshTri.refined(marked), until N >= --max-n.
Load and estimator use a degree-4 rule, like meshfit; errors a degree-6 rule with the exact
gradient. Its time is cumulative wall time of assembly, solve, estimate and refinement; the
error measurement is excluded.

meshfit runs `meshfit solve REQUEST.json --stats` per problem for stats.history (with `exact`,
the errors), again without `exact` for solve_times_ms (its own cumulative clock, the loop
alone, as scikit-fem's; the wall time of that process is reported too), and once more without
--stats for the final vertices. A meshfit without `solve` is skipped.
With --repeat R every run is repeated R times and the median time per step is kept.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from skfem import (Basis, ElementTriP1, Functional, InteriorFacetBasis, LinearForm, MeshTri,
                   adaptive_theta, asm, condense, solve)
from skfem.helpers import dot, grad
from skfem.models.poisson import laplace

ROOT = Path(__file__).resolve().parent.parent
TARGET = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
MU0 = 4e-7 * np.pi
PI = np.pi
COIL = dict(x=(0.2, 0.4), y=(0.3, 0.7), J=1e6)
A_PEAK = 1000.0


def corner_u(x, y):
    return np.hypot(x, y) ** (2 / 3) * np.sin(2 * np.arctan2(y, x) / 3)


def corner_grad(x, y):
    # u_x = -(2/3) r^(-1/3) sin(theta/3), u_y = (2/3) r^(-1/3) cos(theta/3)
    r, t = np.hypot(x, y), np.arctan2(y, x)
    return -2 / 3 * r ** (-1 / 3) * np.sin(t / 3), 2 / 3 * r ** (-1 / 3) * np.cos(t / 3)


def peak_u(x, y):
    return np.exp(-A_PEAK * ((x - 0.5) ** 2 + (y - 0.5) ** 2))


def coil_f(x, y):
    (x0, x1), (y0, y1) = COIL["x"], COIL["y"]
    return COIL["J"] * ((x0 <= x) & (x <= x1) & (y0 <= y) & (y <= y1))


PEAK_R2 = "((x-0.5)^2+(y-0.5)^2)"
# name: (k, f, g, exact u, exact grad u, meshfit request fields)
PROBLEMS = {
    "smooth": (1.0, lambda x, y: 2 * PI ** 2 * np.sin(PI * x) * np.sin(PI * y),
               lambda x, y: 0 * x, lambda x, y: np.sin(PI * x) * np.sin(PI * y),
               lambda x, y: (PI * np.cos(PI * x) * np.sin(PI * y), PI * np.sin(PI * x) * np.cos(PI * y)),
               {"physics": "poisson", "k": "1", "f": "2*pi^2*sin(pi*x)*sin(pi*y)", "g": "0",
                "exact": "sin(pi*x)*sin(pi*y)"}),
    "corner": (1.0, lambda x, y: 0 * x, corner_u, corner_u, corner_grad,
               {"physics": "poisson", "k": "1", "f": "0",
                "g": "(x^2+y^2)^(1/3)*sin(2*atan2(y,x)/3)",
                "exact": "(x^2+y^2)^(1/3)*sin(2*atan2(y,x)/3)"}),
    "peak": (1.0, lambda x, y: peak_u(x, y) * (4 * A_PEAK - 4 * A_PEAK ** 2 * ((x - .5) ** 2 + (y - .5) ** 2)),
             peak_u, peak_u,
             lambda x, y: (-2 * A_PEAK * (x - .5) * peak_u(x, y), -2 * A_PEAK * (y - .5) * peak_u(x, y)),
             {"physics": "poisson", "k": "1", "f": f"(4000-4000000*{PEAK_R2})*exp(-1000*{PEAK_R2})",
              "g": f"exp(-1000*{PEAK_R2})", "exact": f"exp(-1000*{PEAK_R2})"}),
    "magnet": (1 / MU0, coil_f, lambda x, y: 0 * x, None, None,
               {"physics": "magnetostatic", "g": "0",
                "regions": [{"x": list(COIL["x"]), "y": list(COIL["y"]), "current_density": COIL["J"]}]}),
}


def fourier_energy(M):
    """The magnet's W summed over 1 <= m, n <= M, in row blocks to bound the memory."""
    (x0, x1), (y0, y1), J = COIL["x"], COIL["y"], COIL["J"]
    m = np.arange(1, M + 1, dtype=float)
    X2 = ((np.cos(m * PI * x0) - np.cos(m * PI * x1)) / (m * PI)) ** 2
    Y2 = ((np.cos(m * PI * y0) - np.cos(m * PI * y1)) / (m * PI)) ** 2
    s = sum(np.sum(X2[i:i + 256, None] * Y2[None, :] / (m[i:i + 256, None] ** 2 + m[None, :] ** 2))
            for i in range(0, M, 256))
    return MU0 * 16 * J ** 2 * s / (8 * PI ** 2)


def estimator(m, e, basis, u, fk):
    """ex22's residual indicators eta_T^2 (for k constant: f/k in the interior term)."""
    @Functional
    def interior(w):
        return w.h ** 2 * fk(*w.x) ** 2

    fb = [InteriorFacetBasis(m, e, side=i) for i in (0, 1)]
    uf = {f"u{i + 1}": fb[i].interpolate(u) for i in (0, 1)}

    @Functional
    def jump(w):
        return w.h * dot(grad(w["u1"]) - grad(w["u2"]), w.n) ** 2

    per_facet = np.zeros(m.facets.shape[1])
    np.add.at(per_facet, fb[0].find, jump.elemental(fb[0], **uf))
    return interior.elemental(basis) + 0.5 * per_facet[m.t2f].sum(axis=0)


def skfem_run(name, max_n, theta):
    """One adaptive run; a list of per-solve records and the final mesh."""
    k, f, g, exact, exact_grad, _ = PROBLEMS[name]
    m, e = MeshTri.init_tensor(np.linspace(0, 1, 6), np.linspace(0, 1, 6)), ElementTriP1()

    @LinearForm
    def load(v, w):
        return f(*w.x) * v

    @Functional
    def h1_err(w):
        gx, gy = exact_grad(*w.x)
        return (gx - grad(w["uh"])[0]) ** 2 + (gy - grad(w["uh"])[1]) ** 2

    @Functional
    def l2_err(w):
        return (exact(*w.x) - w["uh"]) ** 2

    history, clock = [], 0.0
    while True:
        t0 = time.perf_counter()
        basis = Basis(m, e, intorder=4)
        K, F = k * asm(laplace, basis), asm(load, basis)
        D = m.boundary_nodes()
        x = np.zeros(m.nvertices)
        x[D] = g(*m.p[:, D])
        u = solve(*condense(K, F, x=x, D=D))
        eta2 = k * estimator(m, e, basis, u, lambda x, y: f(x, y) / k)
        clock += time.perf_counter() - t0
        rec = {"vertices": m.nvertices, "estimate": np.sqrt(eta2.sum()), "energy": 0.5 * u @ (K @ u),
               "elapsed_s": clock}
        if exact is not None:
            eb = Basis(m, e, intorder=6)
            uh = eb.interpolate(u)
            rec["energy_error"] = np.sqrt(h1_err.assemble(eb, uh=uh))
            rec["l2_error"] = np.sqrt(l2_err.assemble(eb, uh=uh))
        history.append(rec)
        if m.nvertices >= max_n:
            return history, m.p.T
        t0 = time.perf_counter()
        m = m.refined(adaptive_theta(eta2, theta=theta))
        clock += time.perf_counter() - t0


def meshfit_run(binary, name, args):
    """One `meshfit solve`; (history with elapsed_s, final vertices, wall seconds)."""
    request = {"domain": {"x": [0, 1], "y": [0, 1]}, **PROBLEMS[name][5],
               "max_vertices": args.max_n, "method": args.method, "criterion": args.criterion,
               "growth": args.growth}

    def solve(request, *flags):
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as tmp:
            json.dump(request, tmp)
        try:
            t0 = time.perf_counter()
            run = subprocess.run([binary, "solve", tmp.name, *flags], capture_output=True, text=True,
                                 timeout=3600)
            wall = time.perf_counter() - t0
        finally:
            os.unlink(tmp.name)
        if run.returncode != 0:
            raise RuntimeError(f"exit {run.returncode}: {run.stderr.strip()[:200]}")
        return json.loads(run.stdout), wall

    # The errors come from a run with `exact`; the times from one without, which makes the
    # same meshes bit for bit but measures nothing against u, as scikit-fem's clock does not
    # (--stats prints solve_times_ms, cumulative, and writes no mesh).
    measured, _ = solve(request, "--stats")
    timed, wall = solve({k: v for k, v in request.items() if k != "exact"}, "--stats")
    vertices = np.array(solve(request)[0]["vertices"])[:, :2]
    history = measured["stats"]["history"]
    for h, ms in zip(history, timed["solve_times_ms"]):
        h["elapsed_ms"] = ms
        h["elapsed_s"] = ms / 1000
    return history, vertices, wall


def repeated(run, repeat):
    """run() `repeat` times; the last result with each step's elapsed_s (and wall) the median."""
    runs = [run() for _ in range(repeat)]
    history = runs[-1][0]
    for i, h in enumerate(history):
        h["elapsed_s"] = float(np.median([r[0][i]["elapsed_s"] for r in runs if len(r[0]) > i]))
    return (history, runs[-1][1], *[float(np.median([r[j] for r in runs])) for j in range(2, len(runs[-1]))])


def errors(name, history, W):
    """The convergence measure per step: ||grad e|| (magnet: sqrt(|W - W_h| / W); W_h can pass W
    as the load on triangles cut by the conductor's edges is a quadrature, not exact)."""
    if name == "magnet":
        return np.array([np.sqrt(abs(W - h["energy"]) / W) for h in history])
    return np.array([h["energy_error"] for h in history])


def slope(n, err):
    """Least-squares slope of log err against log N over the second half of the history."""
    half = len(n) // 2
    n, err = np.asarray(n[half:], float), np.asarray(err[half:], float)
    ok = err > 0
    return np.polyfit(np.log(n[ok]), np.log(err[ok]), 1)[0] if ok.sum() >= 2 else float("nan")


def loglog_at(n, xs, ys):
    """ys(xs) interpolated in log-log at n (zeros left out), or None outside the range of xs."""
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    xs, ys = xs[ys > 0], ys[ys > 0]
    if len(xs) == 0 or n < xs[0] or n > xs[-1]:
        return None
    return float(np.exp(np.interp(np.log(n), np.log(xs), np.log(ys))))


def fmt(v, spec=".3e"):
    return "–" if v is None or (isinstance(v, float) and np.isnan(v)) else format(v, spec)


def report(name, sk, mf, W):
    """The markdown table of one problem; meshfit is interpolated to scikit-fem's N."""
    n_sk, e_sk = [h["vertices"] for h in sk], errors(name, sk, W)
    t_sk = [h["elapsed_s"] for h in sk]
    magnet = name == "magnet"
    head = (["N", "skfem W_h", "skfem ΔW/W", "skfem √(ΔW/W)"] if magnet
            else ["N", "skfem ‖∇e‖", "skfem ‖e‖"]) + ["skfem η", "skfem s"]
    if mf:
        head += (["meshfit ΔW/W", "meshfit √(ΔW/W)"] if magnet
                 else ["meshfit ‖∇e‖", "meshfit ‖e‖"]) + ["meshfit s", "skfem s / meshfit s"]
        n_mf, e_mf = [h["vertices"] for h in mf[0]], errors(name, mf[0], W)
        t_mf = [h["elapsed_s"] for h in mf[0]]
        second = e_mf ** 2 if magnet else [h.get("l2_error", 0.0) for h in mf[0]]
    print(f"\n### {name}\n")
    if magnet:
        print(f"ΔW = W - W_h with W = {W:.8e} J/m; √ takes |ΔW| (meshfit's ΔW/W is |ΔW|/W).\n")
    print("| " + " | ".join(head) + " |\n|" + "---:|" * len(head))
    for i, h in enumerate(sk):
        row = [str(h["vertices"])]
        row += ([fmt(h["energy"], ".8e"), fmt((W - h["energy"]) / W), fmt(e_sk[i])] if magnet
                else [fmt(e_sk[i]), fmt(h["l2_error"])])
        row += [fmt(h["estimate"]), fmt(t_sk[i], ".3f")]
        if mf:
            n = h["vertices"]
            e, s, t = loglog_at(n, n_mf, e_mf), loglog_at(n, n_mf, second), loglog_at(n, n_mf, t_mf)
            row += [fmt(s), fmt(e)] if magnet else [fmt(e), fmt(s)]
            row += [fmt(t, ".3f"), fmt(t_sk[i] / t if t else None, ".2f")]
        print("| " + " | ".join(row) + " |")
    print(f"\nslope of {'√(ΔW/W)' if magnet else '‖∇e‖'} vs N over the second half: "
          f"scikit-fem {slope(n_sk, e_sk):.3f}" + (f", meshfit {slope(n_mf, e_mf):.3f}" if mf else ""))
    if mf:
        last = mf[0][-1]
        print(f"\nmeshfit history (N, error, elapsed_ms): "
              + ", ".join(f"({a}, {b:.3e}, {h['elapsed_ms']:.0f})" for a, b, h in zip(n_mf, e_mf, mf[0])))
        print(f"\nfinal: scikit-fem N = {n_sk[-1]}, error {e_sk[-1]:.3e}, {t_sk[-1]:.3f} s; "
              f"meshfit N = {last['vertices']}, error {e_mf[-1]:.3e}, elapsed_ms {last['elapsed_ms']:.0f} "
              f"(process wall {mf[2]:.3f} s)")
    else:
        print("\nmeshfit: not available")


def plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, len(results), figsize=(4.5 * len(results), 8), squeeze=False)
    for j, (name, (sk, mf, W)) in enumerate(results.items()):
        for side, data, style in (("scikit-fem", sk, "o-"), ("meshfit", mf[0] if mf else None, "s--")):
            if data:
                n = [h["vertices"] for h in data]
                axes[0, j].loglog(n, errors(name, data, W), style, ms=3, label=side)
                axes[1, j].loglog(n, [h["elapsed_s"] for h in data], style, ms=3, label=side)
        n = np.array([sk[0]["vertices"], sk[-1]["vertices"]], float)
        axes[0, j].loglog(n, errors(name, sk, W)[-1] * (n / n[1]) ** -0.5, "k:", label="N^-1/2")
        axes[0, j].set_title(name)
        axes[0, j].set_ylabel("relative energy-norm error" if name == "magnet" else "‖∇(u - u_h)‖")
        axes[1, j].set_ylabel("cumulative time (s)")
        axes[1, j].set_xlabel("vertices N")
        axes[0, j].legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--meshfit", type=Path, default=TARGET / "release" / "meshfit")
    parser.add_argument("--max-n", type=int, default=20000, help="stop once N >= this (e.g. 100000)")
    parser.add_argument("--repeat", type=int, default=1, help="runs per side; median time kept")
    parser.add_argument("--problems", nargs="+", choices=list(PROBLEMS), default=list(PROBLEMS))
    parser.add_argument("--theta", type=float, default=0.5, help="scikit-fem's adaptive_theta")
    parser.add_argument("--method", default="semi-recursive")
    parser.add_argument("--criterion", default="residual")
    parser.add_argument("--growth", type=float, default=1.5)
    parser.add_argument("--plot", type=Path, default=ROOT / "bench" / "out" / "solve.png")
    args = parser.parse_args()

    W = None
    if "magnet" in args.problems:
        W, W_half = fourier_energy(4000), fourier_energy(2000)
        # The tail of the double sum falls like M^-3, so the tail beyond M is about
        # (W_M - W_M/2) / 7.
        print(f"Magnet reference: W = {W:.12e} J/m (m, n <= 4000); W_4000 - W_2000 = "
              f"{W - W_half:.2e}, truncation ≈ {(W - W_half) / 7:.1e} ({(W - W_half) / 7 / W:.1e} relative)")
    results = {}
    for name in args.problems:
        print(f"{name}: scikit-fem ...", file=sys.stderr)
        sk, sk_p = repeated(lambda: skfem_run(name, args.max_n, args.theta), args.repeat)
        mf = None
        try:
            print(f"{name}: meshfit ...", file=sys.stderr)
            mf = repeated(lambda: meshfit_run(args.meshfit, name, args), args.repeat)
        except (OSError, RuntimeError, ValueError, KeyError, subprocess.TimeoutExpired) as err:
            print(f"{name}: meshfit: not available ({err})", file=sys.stderr)
        results[name] = (sk, mf, W)
        report(name, sk, mf, W)
        if name == "corner":
            for side, p in (("scikit-fem", sk_p), ("meshfit", mf[1] if mf else None)):
                if p is not None:
                    r = np.hypot(p[:, 0], p[:, 1])
                    print(f"\n{side}: N = {len(p)}, nearest vertex to the corner (0, 0) at r = "
                          f"{r[r > 0].min():.3e}")
    plot(results, args.plot)
    print(f"\nplot: {args.plot}", file=sys.stderr)


if __name__ == "__main__":
    main()
