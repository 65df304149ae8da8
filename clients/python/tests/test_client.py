"""The client against the real server: SERVER_BINARY names the binary (cargo test runs these
through tests/python_client.rs with its own build)."""

import math
import os
import socket
import subprocess
import time

import httpx
import numpy as np
import pytest

import meshfit


@pytest.fixture(scope="module")
def client():
    binary = os.environ.get("SERVER_BINARY", "target/release/meshfit")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    # The server refuses MESHFIT_ settings it does not know: it gets only its own.
    env = {k: v for k, v in os.environ.items() if not k.startswith("MESHFIT_")}
    env.update(MESHFIT_ADDR=f"127.0.0.1:{port}", MESHFIT_LOG="warn")
    server = subprocess.Popen([binary], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    for _ in range(200):
        try:
            if httpx.get(f"{base}/healthz").status_code == 200:
                break
        except httpx.HTTPError:
            time.sleep(0.05)
    with meshfit.Client(base) as c:
        yield c
    server.terminate()
    server.wait()


def f(x, y):
    """Sums and products alone: the server's expression gives the same bits."""
    return x * y * y - 0.5 * x + y


def test_learn_meshes_the_callers_f_as_the_server_meshes_its_expression(client):
    mine = client.learn(f, x=(-1, 2), y=(0, 1), max_vertices=300, workers=3, progress=False)
    assert mine.vertices.shape == (300, 2) and mine.values.shape == (300,)
    assert mine.triangles.shape[1] == 3 and mine.triangles.max() == 299
    assert mine.evaluations["told"] == mine.evaluations["asked"] >= 300
    assert mine.stats["vertices"] == 300
    assert mine.job_id and client.job(mine.job_id).status()["status"] == "succeeded"
    theirs = client.mesh("x*y*y - 0.5*x + y", x=(-1, 2), y=(0, 1), max_vertices=300, criterion="curvature")
    np.testing.assert_array_equal(mine.vertices, theirs.vertices)
    np.testing.assert_array_equal(mine.values, theirs.values)
    np.testing.assert_array_equal(mine.triangles, theirs.triangles)
    # Every value is F at its vertex.
    np.testing.assert_array_equal(mine.values, f(mine.vertices[:, 0], mine.vertices[:, 1]))


def test_a_run_started_from_another_evaluates_only_new_points(client):
    calls = []

    def counted(x, y):
        calls.append((x, y))
        return f(x, y)

    first = client.learn(counted, max_vertices=200, progress=False)
    assert len(calls) == first.evaluations["asked"]
    calls.clear()
    again = client.learn(counted, max_vertices=150, progress=False, start_from=first)
    assert calls == [] and np.array_equal(again.vertices, first.vertices[:150])
    larger = client.learn(counted, max_vertices=300, progress=False, start_from=first.job_id)
    assert 100 <= len(calls) < 200, len(calls)
    assert set(map(tuple, first.vertices)) <= set(map(tuple, larger.vertices))


def test_points_where_f_raises_or_is_nan_fail_and_the_mesh_goes_on(client):
    failures = {"raised": 0, "nan": 0}

    def fragile(x, y):
        # Lines a mesh of the square halves on its way: both kinds of failure are met.
        if x == 0.5 and 0 < y < 1:
            failures["raised"] += 1
            raise RuntimeError("the simulation diverged")
        if y == 0.5 and 0 < x < 1:
            failures["nan"] += 1
            return math.nan
        return math.sin(3 * x) * y

    result = client.learn(fragile, max_vertices=200, progress=False)
    assert result.stats["vertices"] == 200
    assert failures["raised"] >= 1 and failures["nan"] >= 1, failures
    assert result.evaluations["failed"] == failures["raised"] + failures["nan"]
    assert np.isfinite(result.values).all()


def test_errors_carry_the_problem_document(client):
    with pytest.raises(meshfit.MeshfitError) as refused:
        client.mesh("sin(x) + q")
    assert refused.value.status == 422 and refused.value.problem["column"] == 10
    with pytest.raises(meshfit.MeshfitError) as refused:
        client.learn(f, max_vertices=100, criterion="error", progress=False)
    assert refused.value.field == "/criterion"


def test_a_grid_a_solution_events_and_downloads(client, tmp_path):
    heights = np.add.outer(np.arange(20.0), np.arange(30.0) ** 2)  # heights[j, i], 20 rows of 30
    grid = client.mesh(heights, max_vertices=100)
    assert grid.vertices[:, 0].max() == 29 and grid.vertices[:, 1].max() == 19
    solution = client.solve({"f": "2*pi^2*sin(pi*x)*sin(pi*y)", "max_vertices": 500})
    assert solution.stats["physics"] == "poisson" and abs(solution.values.max() - 1) < 0.05
    job = client.job(solution.job_id)
    events = list(job.events())
    assert events[-1]["event"] == "result" and events[-1]["data"]["status"] == "succeeded"
    job.download("obj", tmp_path / "u.obj")
    assert (tmp_path / "u.obj").read_text().startswith("#")
