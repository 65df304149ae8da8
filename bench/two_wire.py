"""The two-wire line's inductance against its formula, as docs/solve.md's table shows it.

    cargo build --release && python3 bench/two_wire.py [--meshfit target/release/meshfit]

Two round copper wires of radius 2 mm (64-gons), centres 20 mm apart, ±10 A on one circuit, in
an 800 mm box; at direct current L = μ0/π (ln(d/a) + 1/4) per metre.
"""
import argparse
import json
import math
import subprocess
import tempfile

MU_0 = 1.25663706212e-6
A, D, SIDES = 2.0, 20.0, 64


def disc(x):
    return [[x + A * math.cos(2 * math.pi * k / SIDES), A * math.sin(2 * math.pi * k / SIDES)] for k in range(SIDES)]


def request(max_vertices):
    return {
        "physics": "magnetostatic",
        "unit": "mm",
        "domain": {"x": [-400, 400], "y": [-400, 400]},
        "circuits": {"line": {"current": 10}},
        "regions": [
            {"name": "go", "material": "copper", "circuit": "line", "polygon": disc(-D / 2)},
            {"name": "return", "material": "copper", "circuit": "line", "direction": -1, "polygon": disc(D / 2)},
        ],
        "max_vertices": max_vertices,
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--meshfit", default="target/release/meshfit")
    args = parser.parse_args()
    exact = MU_0 / math.pi * (math.log(D / A) + 0.25)
    print(f"exact {exact * 1e6:.6f} µH/m\n")
    print("| vertices | inductance (µH/m) | error | incremental (µH/m) |\n|---|---|---|---|")
    for n in [1000, 3000, 10000, 30000, 100000]:
        with tempfile.NamedTemporaryFile("w", suffix=".json") as f:
            json.dump(request(n), f)
            f.flush()
            out = subprocess.run([args.meshfit, "solve", f.name, "--stats"], check=True, capture_output=True)
        line = json.loads(out.stdout)["stats"]["circuits"]["line"]
        l, dl = line["inductance"], line["incremental_inductance"]
        print(f"| {n:,} | {l * 1e6:.6f} | {(l - exact) / exact * 100:+.3g}% | {dl * 1e6:.6f} |")


if __name__ == "__main__":
    main()
