"""The meshfit client: your own F meshed by ask/tell, expressions, grids and problems."""

from __future__ import annotations

import json
import math
import os
import sys
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Optional, Sequence, Tuple, Union

import httpx
import numpy as np

# The server holds an ask this long at most; the client waits a little longer for the answer.
ASK_WAIT_MS = 9000


class MeshfitError(Exception):
    """A request the server refused or a job that failed, with the server's problem document
    (RFC 9457: `type`, `title`, `status`, `detail`, and where: `field`, `column`, `point`)."""

    def __init__(self, problem: dict):
        self.problem = problem
        self.status = problem.get("status")
        self.field = problem.get("field")
        super().__init__(problem.get("detail") or problem.get("title") or "meshfit request failed")


@dataclass
class Result:
    """A mesh: `vertices` (n, 2), `values` (n,) (F, or u for a solution), `triangles` (m, 3)
    counter-clockwise vertex indices, the server's `stats`, a client job's `evaluations`."""

    vertices: np.ndarray
    values: np.ndarray
    triangles: np.ndarray
    stats: dict
    job_id: Optional[str] = None
    evaluations: Optional[dict] = None
    document: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_document(cls, doc: dict, job_id: Optional[str] = None, evaluations: Optional[dict] = None) -> "Result":
        points = np.asarray(doc["vertices"], dtype=float).reshape(-1, 3)
        return cls(
            vertices=points[:, :2].copy(),
            values=points[:, 2].copy(),
            triangles=np.asarray(doc["triangles"], dtype=np.int64).reshape(-1, 3),
            stats=doc.get("stats", {}),
            job_id=job_id or doc.get("id"),
            evaluations=evaluations,
            document=doc,
        )


class Job:
    """A job on the server, by id: its status, events, mesh and files."""

    def __init__(self, client: "Client", job_id: str):
        self.client = client
        self.id = job_id

    def status(self) -> dict:
        """`GET /v1/jobs/{id}`: status, progress, stats, a client job's evaluations."""
        return self.client._request("GET", f"/v1/jobs/{self.id}").json()

    def events(self) -> Iterator[dict]:
        """The job's server-sent events, each `{"event", "id", "data"}`, until its `result`
        or `error` event; a client job's `ask` events carry each batch's points. A stream the
        server ends before that (a client job's, after a quiet spell) is resumed from the last
        event seen, as a browser's EventSource does."""
        last_id = None
        while True:
            headers = {"accept": "text/event-stream"}
            if last_id is not None:
                headers["last-event-id"] = last_id
            with self.client._http.stream("GET", f"/v1/jobs/{self.id}/events", headers=headers, timeout=None) as r:
                if r.status_code == 204:
                    return  # the final event was seen
                if r.status_code >= 400:
                    r.read()
                    raise self.client._error(r)
                event: dict = {}
                for line in r.iter_lines():
                    if line.startswith(":"):
                        continue
                    if not line:
                        if "data" in event:
                            event["data"] = json.loads(event["data"])
                            last_id = event.get("id", last_id)
                            yield event
                            if event.get("event") in ("result", "error"):
                                return
                        event = {}
                        continue
                    name, _, value = line.partition(":")
                    value = value[1:] if value.startswith(" ") else value
                    event[name] = event[name] + "\n" + value if name == "data" and name in event else value

    def result(self) -> Result:
        """The finished mesh as arrays."""
        doc = self.client._request("GET", f"/v1/jobs/{self.id}/mesh").json()
        return Result.from_document(doc, self.id, self.status().get("evaluations"))

    def download(self, format: str, path: Union[str, os.PathLike]) -> None:
        """Writes the finished mesh in `format` (json, obj, ply, stl, vtu, msh, glb, svg, png, ...)
        to `path`."""
        with self.client._http.stream("GET", f"/v1/jobs/{self.id}/mesh", params={"format": format}) as r:
            if r.status_code >= 400:
                r.read()
                raise self.client._error(r)
            with open(path, "wb") as out:
                for chunk in r.iter_bytes():
                    out.write(chunk)

    def cancel(self) -> dict:
        """`DELETE /v1/jobs/{id}`: its final status."""
        return self.client._request("DELETE", f"/v1/jobs/{self.id}").json()


def _evaluate(f: Callable[[float, float], Any], x: float, y: float) -> Tuple[Optional[float], Optional[str]]:
    """F at (x, y), or None and why: an exception, or a value that is not a finite number."""
    try:
        value = float(f(x, y))
    except Exception as e:  # the caller's F may fail in any way: the point fails, not the run
        return None, f"{type(e).__name__}: {e}"[:500]
    return (value, None) if math.isfinite(value) else (None, f"not finite: {value}")


class Client:
    """A meshfit server at `base_url`, with an API key when it has keys."""

    def __init__(self, base_url: str = "http://localhost:8080", api_key: Optional[str] = None, timeout: float = 60.0):
        headers = {"authorization": f"Bearer {api_key}"} if api_key else {}
        self._http = httpx.Client(base_url=base_url.rstrip("/"), headers=headers, timeout=timeout)

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def _error(self, response: httpx.Response) -> MeshfitError:
        try:
            problem = response.json()
        except ValueError:
            problem = {"status": response.status_code, "detail": response.text[:500]}
        return MeshfitError(problem)

    def _request(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        response = self._http.request(method, path, **kwargs)
        if response.status_code >= 400:
            raise self._error(response)
        return response

    def job(self, job_id: str) -> Job:
        """The job `job_id`."""
        return Job(self, job_id)

    def learn(
        self,
        f: Callable[[float, float], Any],
        x: Sequence[float] = (0.0, 1.0),
        y: Sequence[float] = (0.0, 1.0),
        max_vertices: int = 10_000,
        tolerance: Optional[float] = None,
        workers: int = 1,
        progress: bool = True,
        pool: str = "thread",
        start_from: Union[str, "Result", None] = None,
        **options: Any,
    ) -> Result:
        """Meshes your own `f(x, y)` on [x0, x1] × [y0, y1]: the server asks for points in
        batches, `f` runs on `workers` threads (or processes, `pool="process"`, for a picklable
        `f`), and the values go back, until the mesh has `max_vertices` (or its worst
        criterion value is at most `tolerance`). A point where `f` raises or returns NaN
        fails: the mesh takes the criterion's guess there and goes on. Other `options`
        (`criterion`: `curvature`, the default, or `variation`; `min_size`, `max_size`,
        `method`, `batch`, `lease_ms`) go into the request; `batch` defaults to 4 points a
        worker, at least 16. `start_from` (an earlier result of the same `f`, or its job id)
        reuses every value that job was told: a smaller budget evaluates nothing, a larger
        one only the new points.
        Interrupted, the job stays on the server: `client.job(id)` and another loop resume it.
        """
        body: dict = {"source": "client", "domain": {"x": list(x), "y": list(y)}, "max_vertices": max_vertices}
        if tolerance is not None:
            body["tolerance"] = tolerance
        body.setdefault("batch", max(16, 4 * workers, math.ceil(max_vertices / 10_000)))
        if start_from is not None:
            body["from"] = start_from.job_id if isinstance(start_from, Result) else start_from
        body.update(options)
        job_id = self._request("POST", "/v1/jobs", json=body).json()["id"]
        # One thread evaluates in place: a pool would only add its hand-offs to every point.
        executor: Optional[Executor] = None
        if workers > 1 or pool == "process":
            executor = (ProcessPoolExecutor if pool == "process" else ThreadPoolExecutor)(max_workers=workers)
        bar = _progress(max_vertices) if progress else None
        try:
            self._play(job_id, f, executor, bar)
        finally:
            if executor is not None:
                executor.shutdown(wait=False, cancel_futures=True)
            if bar is not None:
                bar.close()
        job = self.job(job_id)
        status = job.status()
        if status["status"] != "succeeded":
            raise MeshfitError(status.get("problem") or {"detail": f"the job ended {status['status']}"})
        return job.result()

    def _play(self, job_id: str, f: Callable[[float, float], Any], executor: Optional[Executor], bar: Any) -> None:
        """Asks and tells until the job finishes: one request a batch, each tell bringing the
        next batch back (`tell?ask=`)."""
        timeout = ASK_WAIT_MS / 1000 + self._http.timeout.read if self._http.timeout.read else None
        ask = self._ask(job_id, timeout)
        while ask["status"] == "running":
            points = ask["points"]
            if executor is None:
                results = [_evaluate(f, p["x"], p["y"]) for p in points]
            else:
                futures = [executor.submit(_evaluate, f, p["x"], p["y"]) for p in points]
                results = [future.result() for future in futures]
            values = []
            for p, (value, reason) in zip(points, results):
                entry: dict = {"id": p["id"], "value": value}
                if reason is not None:
                    entry["reason"] = reason
                values.append(entry)
            told = self._request(
                "POST", f"/v1/jobs/{job_id}/tell", params={"ask": ASK_WAIT_MS}, json={"values": values}, timeout=timeout
            ).json()
            if bar is not None:
                bar.update(min(told["evaluations"]["told"], bar.total) - bar.n)
            ask = told.get("next") or self._ask(job_id, timeout)

    def _ask(self, job_id: str, timeout: Optional[float]) -> dict:
        """The job's next batch, or its end: long polls until one comes."""
        while True:
            response = self._http.get(f"/v1/jobs/{job_id}/ask", params={"wait": ASK_WAIT_MS}, timeout=timeout)
            if response.status_code == 204:
                continue
            if response.status_code >= 400:
                raise self._error(response)
            return response.json()

    def mesh(
        self,
        source: Union[str, np.ndarray, Sequence[Sequence[float]]],
        x: Optional[Sequence[float]] = None,
        y: Optional[Sequence[float]] = None,
        **options: Any,
    ) -> Result:
        """Meshes an expression in x and y, or a 2-D array of samples `heights[j, i]` at
        (x_i, y_j) (x along the rows' length), on the server. `options`: `max_vertices`,
        `tolerance`, `method`, `criterion`, `min_angle`, ..."""
        if isinstance(source, str):
            body: dict = {"function": source}
        else:
            grid = np.asarray(source, dtype=float)
            if grid.ndim != 2:
                raise ValueError(f"a grid is a 2-D array, got {grid.ndim} dimensions")
            ny, nx = grid.shape
            body = {"grid": {"nx": nx, "ny": ny, "values": grid.ravel().tolist()}}
        if x is not None and y is not None:
            body["domain"] = {"x": list(x), "y": list(y)}
        body.update(options)
        doc = self._request("POST", "/v1/meshes", json=body).json()
        return Result.from_document(doc)

    def solve(self, problem: dict) -> Result:
        """Solves a boundary value problem (the body of `POST /v1/solutions`): `values` is u."""
        doc = self._request("POST", "/v1/solutions", json=problem).json()
        return Result.from_document(doc)


def _progress(total: int) -> Any:
    """A tqdm bar on a terminal when tqdm is installed, else nothing."""
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="pt", disable=not sys.stderr.isatty())
