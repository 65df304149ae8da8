#!/usr/bin/env python3
"""What meshio, an independent reader, finds in each file format meshfit writes.

Run by hand, never in CI (it needs packages from PyPI):

    python3 -m venv bench/.venv && bench/.venv/bin/pip install meshio numpy
    bench/.venv/bin/python bench/formats.py > docs/formats.md

It builds the release binary, writes one mesh in every format with `meshfit mesh --output
/tmp/meshfit-formats.FORMAT`, and reads each file back with meshio. The JSON document is the
reference: per format the table gives what meshio read (points, cells, point and cell data)
against the expected counts, and the largest difference between the triangle corners it read
and the reference's (a format that writes f32 differs by rounding; msh writes the plane mesh,
so its z comes from the point data "z"). The binary is `$CARGO_TARGET_DIR/release/meshfit`
when that variable is set, else `target/release/meshfit`.
"""

import contextlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TARGET = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
MESHFIT = TARGET / "release" / "meshfit"
FUNCTION = "exp(-100*((x-0.4)^2+(y-0.6)^2))"
MAX_VERTICES = 2000
# Every format the CLI may know, with the criterion to mesh by; one it does not know on this
# branch is reported as such. ply comes twice: with the triangle errors (criterion error) as a
# face property and without (criterion variation), because meshio reads only the latter.
ROWS = [("obj", "error"), ("ply", "error"), ("ply", "variation"), ("stl", "error"),
        ("vtu", "error"), ("msh", "error"), ("glb", "error"), ("svg", "error"), ("png", "error")]
# Formats meshio has no reader for.
NO_READER = {"glb", "svg", "png"}


NOTES = """
- **ply with errors**: meshio's binary PLY reader takes a face element property by property
  (every face's `vertex_indices`, then every face's `error`), but PLY stores each face's
  properties together, so a face with any property besides `vertex_indices` fails to read.
  The same file without `error` (criterion variation) reads. ply-rs-bw (in the unit tests)
  and, checked by hand, plyfile 1.1.5 read the errors back exactly.
- **glb**: meshio has no glTF reader. The unit tests read it with the gltf crate; checked by
  hand, the Khronos glTF-Validator (2.0.0-dev.3.10) reports no errors, warnings or hints.
- **svg, png**: pictures, not meshes; meshio has no reader for either.
- **msh**: `gmsh:dim_tags` and `gmsh:geometrical` are meshio's own bookkeeping of the one
  surface entity; `z` and `error` are the views the file holds.
"""


def write(fmt, criterion="error"):
    """Writes the mesh in `fmt`; returns its path, or None if this meshfit has no such format."""
    path = Path(f"/tmp/meshfit-formats-{criterion}.{fmt}")
    run = subprocess.run(
        [MESHFIT, "mesh", "--function", FUNCTION, "--max-vertices", str(MAX_VERTICES),
         "--criterion", criterion, "--format", fmt, "--output", path],
        capture_output=True, text=True)
    if run.returncode != 0:
        if "unknown format" in run.stderr:
            return None
        sys.exit(f"meshfit failed for {fmt}: {run.stderr}")
    return path


def corner_difference(mesh, fmt, vertices, triangles):
    """The largest |difference| between the triangle corners meshio read and the reference."""
    got = [c for c in mesh.cells if c.type == "triangle"]
    if not got or len(got[0].data) != len(triangles):
        return "n/a"
    points = np.array(mesh.points, dtype=float)
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    if fmt == "msh":
        points[:, 2] = np.asarray(mesh.point_data["z"]).reshape(-1)
    return f"{np.max(np.abs(points[got[0].data] - vertices[triangles])):.1e}"


def reference(criterion):
    """The vertices and triangles of the JSON document, as arrays."""
    document = json.loads(write("json", criterion).read_text())
    return np.array(document["vertices"], dtype=float), np.array(document["triangles"], dtype=np.int64)


def main():
    import meshio

    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    references = {c: reference(c) for c in ("error", "variation")}
    n, m = (len(a) for a in references["error"])
    n_var, m_var = (len(a) for a in references["variation"])

    print("# What meshio reads in each format\n")
    print("Made by hand with the command below (not in CI). The expected counts come from the")
    print(f"JSON document of the same mesh: F = `{FUNCTION}`, `--max-vertices {MAX_VERTICES}`;")
    print(f"criterion `error` (each triangle's error known) gives **{n} points, {m} triangles**,")
    print(f"criterion `variation` (no errors) **{n_var} points, {m_var} triangles**.")
    print(f"meshio {meshio.__version__}, numpy {np.__version__}. The last column is the largest")
    print("difference between a triangle corner meshio read and the document's (0 for exact f64,")
    print("f32 rounding for stl; msh's z is its point data `z`).\n")
    print("```")
    print("python3 -m venv bench/.venv && bench/.venv/bin/pip install meshio numpy")
    print("bench/.venv/bin/python bench/formats.py > docs/formats.md")
    print("```\n")
    print("| format | criterion | meshio reads it | points | cells | point data | cell data "
          "| max corner difference |")
    print("|---|---|---|---|---|---|---|---|")
    for fmt, criterion in ROWS:
        vertices, triangles = references[criterion]
        row = f"| {fmt} | {criterion} |"
        path = write(fmt, criterion)
        if path is None:
            print(f"{row} no: meshfit has no such format on this branch | | | | | |")
            continue
        try:
            # meshio prints the failures of formats it tries before the right one (.msh is
            # also ANSYS) to stdout, and exits on a file it cannot read at all.
            with contextlib.redirect_stdout(sys.stderr):
                mesh = meshio.read(path)
        except (Exception, SystemExit) as e:
            reason = (str(e).strip().splitlines() or [type(e).__name__])[0]
            if fmt in NO_READER:
                reason = f"meshio has no reader for {fmt} ({reason})"
            print(f"{row} no: {reason} | | | | | |")
            continue
        cells = ", ".join(f"{c.type} {len(c.data)}" for c in mesh.cells)
        point_data = ", ".join(sorted(mesh.point_data)) or "-"
        cell_data = ", ".join(sorted(mesh.cell_data)) or "-"
        difference = corner_difference(mesh, fmt, vertices, triangles)
        print(f"{row} yes | {len(mesh.points)} of {len(vertices)} | {cells} (of {len(triangles)}) "
              f"| {point_data} | {cell_data} | {difference} |")
    print(NOTES)


if __name__ == "__main__":
    main()
