"""Devices with exact answers, solved at 10^3 to 10^5 vertices: docs/solve.md's tables.

    cargo build --release && python3 bench/devices.py [--meshfit target/release/meshfit] [CASE ...]

Each case is a request as an engineer writes it (mm, named regions, circuits, round parts drawn
with arcs), run through `meshfit solve`; the table gives the figure, its error against the
exact answer and the slope of log |error| against log N. Cases: two-wire, coax, ring-core,
solenoid, solenoid-disc, loops.
"""
import argparse
import json
import math
import subprocess
import tempfile

MU_0 = 1.25663706212e-6
SIZES = [1000, 3000, 10000, 30000, 100000]


def disc(x, y, r, segment=2.0):
    arc = {"arc": 180, "max_segment_angle": segment}
    return [[x + r, y], arc, [x - r, y], arc]


def magnetostatic(**fields):
    return {"physics": "magnetostatic", "unit": "mm", **fields}


def elliptic(m):
    """K(m) and E(m) by the arithmetic-geometric mean."""
    a, b, total, power = 1.0, math.sqrt(1.0 - m), m / 2.0, 0.5
    for _ in range(40):
        a, b, c = (a + b) / 2.0, math.sqrt(a * b), (a - b) / 2.0
        power *= 2.0
        total += power * c * c
    k = math.pi / (2.0 * a)
    return k, k * (1.0 - total)


def two_wire():
    """Round copper wires, a = 2 mm (64-gons), centres 20 mm apart, ±10 A, 800 mm box."""
    a, d = 2.0, 20.0
    request = magnetostatic(
        domain={"x": [-400, 400], "y": [-400, 400]},
        circuits={"line": {"current": 10}},
        regions=[
            {"name": "go", "material": "copper", "circuit": "line", "polygon": disc(-d / 2, 0, a, 5.625)},
            {"name": "return", "material": "copper", "circuit": "line", "direction": -1,
             "polygon": disc(d / 2, 0, a, 5.625)},
        ],
    )
    exact = MU_0 / math.pi * (math.log(d / a) + 0.25)
    return "L (µH/m)", request, lambda doc: doc["stats"]["circuits"]["line"]["inductance"], exact, 1e6


def coax():
    """Core a = 1 mm, return conductor 3 to 4 mm (two half rings of half a turn), 10 A."""
    a, b, c = 1.0, 3.0, 4.0
    arc = lambda degrees: {"arc": degrees, "max_segment_angle": 2}
    request = magnetostatic(
        domain={"x": [-8, 8], "y": [-8, 8]},
        circuits={"line": {"current": 10}},
        regions=[
            {"name": "core", "material": "copper", "circuit": "line", "polygon": disc(0, 0, a)},
            {"name": "upper return", "material": "copper", "circuit": "line", "direction": -1, "turns": 0.5,
             "polygon": [[b, 0], [c, 0], arc(180), [-c, 0], [-b, 0], arc(-180)]},
            {"name": "lower return", "material": "copper", "circuit": "line", "direction": -1, "turns": 0.5,
             "polygon": [[-b, 0], [-c, 0], arc(180), [c, 0], [b, 0], arc(-180)]},
        ],
    )
    b2, c2 = b * b, c * c
    outer = c2 * c2 / (c2 - b2) ** 2 * math.log(c / b) - (3 * c2 - b2) / (4 * (c2 - b2))
    exact = MU_0 / (2 * math.pi) * (math.log(b / a) + 0.25 + outer)
    return "L (µH/m)", request, lambda doc: doc["stats"]["circuits"]["line"]["inductance"], exact, 1e6


def ring_core():
    """A core of μr 10^4 from 10 to 15 mm, 10 mm deep, 50 turns at 1 A through its hole."""
    request = magnetostatic(
        depth=10,
        domain={"x": [-40, 40], "y": [-40, 40]},
        materials={"core": {"mu_r": 10000}},
        circuits={"winding": {"current": 1}},
        regions=[
            {"name": "core", "material": "core", "polygon": disc(0, 0, 15)},
            {"name": "hole", "material": "air", "polygon": disc(0, 0, 10)},
            {"name": "in", "material": "copper", "circuit": "winding", "turns": 50, "x": [-2, 2], "y": [-2, 2]},
            {"name": "out", "material": "copper", "circuit": "winding", "turns": 50, "direction": -1,
             "x": [17, 21], "y": [-2, 2]},
        ],
    )
    exact = 0.01 * 50**2 * MU_0 * 1e4 * math.log(1.5) / (2 * math.pi)
    return "L (mH)", request, lambda doc: doc["stats"]["circuits"]["winding"]["inductance"], exact, 1e3


def holding(doc, x, y):
    """The triangle of a solution document that holds (x, y), and (x, y)'s barycentric weights."""
    v = doc["vertices"]
    for t, (i, j, k) in enumerate(doc["triangles"]):
        (x1, y1), (x2, y2), (x3, y3) = v[i][:2], v[j][:2], v[k][:2]
        det = (x2 - x1) * (y3 - y1) - (x3 - x1) * (y2 - y1)
        l2 = ((x - x1) * (y3 - y1) - (x3 - x1) * (y - y1)) / det
        l3 = ((x2 - x1) * (y - y1) - (x - x1) * (y2 - y1)) / det
        if l2 >= 0 and l3 >= 0 and l2 + l3 <= 1:
            return t, (1 - l2 - l3, l2, l3)
    raise ValueError(f"no triangle holds ({x}, {y})")


def thick_solenoid():
    """100 turns at 1 A on r 10–12 mm, z ±20 mm, in an open box of 80 × 200 mm, and B_z on its axis in T."""
    a1, a2, b = 10.0, 12.0, 20.0
    request = magnetostatic(
        geometry="axisymmetric",
        domain={"x": [0, 80], "y": [-100, 100]},
        boundary="open",
        circuits={"coil": {"current": 1}},
        regions=[{"name": "coil", "material": "copper", "circuit": "coil", "turns": 100, "x": [a1, a2], "y": [-b, b]}],
    )
    j = 100 / ((a2 - a1) * 2 * b * 1e-6)
    end = lambda x: x * math.log((a2 + math.hypot(a2, x)) / (a1 + math.hypot(a1, x)))
    return request, lambda z: MU_0 * j / 2 * (end(z + b) - end(z - b)) * 1e-3


def solenoid():
    """100 turns at 1 A on r 10–12 mm, z ±20 mm, open box 80 × 200 mm: B_z on the axis at z = 10 mm, the triangle's (as /evaluate answers)."""
    request, axial = thick_solenoid()
    return "B_z (mT)", request, lambda doc: doc["flux_density"][holding(doc, 0.01, 10.0)[0]][1], axial(10.0), 1e3


def solenoid_disc():
    """The same solenoid: the flux through the disc r ≤ 1 mm at z = 10 mm over its area, 2 A(1 mm) / 1 mm."""
    request, axial = thick_solenoid()
    rho, z, h = 1.0, 10.0, 0.5
    # The disc's mean B_z is the axis's less ρ²/8 of its second derivative in z.
    second = (axial(z + h) - 2 * axial(z) + axial(z - h)) / (h * h)
    exact = axial(z) - rho * rho / 8 * second

    def mean(doc):
        t, weights = holding(doc, rho, z)
        a = sum(w * doc["vertices"][v][2] for w, v in zip(weights, doc["triangles"][t]))
        return 2 * a / (rho * 1e-3)

    return "flux / area (mT)", request, mean, exact, 1e3


def loops():
    """Rings of round wire (a = 1 mm) on R = 20 and 30 mm, 10 mm apart, 100 A each: the pull on the lower."""
    r1, r2, gap = 20.0, 30.0, 10.0
    request = magnetostatic(
        geometry="axisymmetric",
        domain={"x": [0, 80], "y": [-50, 60]},
        boundary="open",
        circuits={"pair": {"current": 100}},
        regions=[
            {"name": "lower", "material": "copper", "circuit": "pair", "polygon": disc(r1, 0, 1, 7.5)},
            {"name": "upper", "material": "copper", "circuit": "pair", "polygon": disc(r2, gap, 1, 7.5)},
        ],
    )
    r1, r2, z = r1 * 1e-3, r2 * 1e-3, gap * 1e-3
    k, e = elliptic(4 * r1 * r2 / ((r1 + r2) ** 2 + z * z))
    factor = (r1 * r1 + r2 * r2 + z * z) / ((r1 - r2) ** 2 + z * z)
    exact = 100**2 * MU_0 * z / math.sqrt((r1 + r2) ** 2 + z * z) * (factor * e - k)
    return "F_z (mN)", request, lambda doc: doc["stats"]["regions"][0]["force"][1], exact, 1e3


CASES = {
    "two-wire": two_wire,
    "coax": coax,
    "ring-core": ring_core,
    "solenoid": solenoid,
    "solenoid-disc": solenoid_disc,
    "loops": loops,
}


def solve(meshfit, request, stats_only):
    with tempfile.NamedTemporaryFile("w", suffix=".json") as f:
        json.dump(request, f)
        f.flush()
        flags = ["--stats"] if stats_only else []
        out = subprocess.run([meshfit, "solve", f.name, *flags], check=True, capture_output=True)
    return json.loads(out.stdout)


def slope(rows):
    xs = [math.log(n) for n, _ in rows]
    ys = [math.log(abs(err)) for _, err in rows]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--meshfit", default="target/release/meshfit")
    parser.add_argument("cases", nargs="*", default=list(CASES))
    args = parser.parse_args()
    for name in args.cases:
        label, request, figure, exact, scale = CASES[name]()
        print(f"### {name}: {CASES[name].__doc__}\n\nexact {exact * scale:.6g}\n")
        print(f"| vertices | {label} | error |\n|---|---|---|")
        rows = []
        for n in SIZES:
            doc = solve(args.meshfit, {**request, "max_vertices": n}, not name.startswith("solenoid"))
            value = figure(doc)
            rows.append((n, (value - exact) / exact))
            print(f"| {n:,} | {value * scale:.6g} | {rows[-1][1] * 100:+.3g}% |")
        print(f"\nslope of log |error| against log N: {slope(rows):.2f}\n")


if __name__ == "__main__":
    main()
