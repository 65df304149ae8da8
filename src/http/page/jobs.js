// Running a job: POST /v1/jobs, then its events, into `view`.

import { $, view } from "./state.js";
import { fmt } from "./colours.js";
import { authHeaders, clearErrors, curlLine, showError, showProblem, showTab, updateAddress } from "./form.js";
import { loadErrors, showDownloads, showStats } from "./downloads.js";
import { scheduleDraw } from "./viewer.js";
import { drawConvergence } from "./plots.js";

export async function run(req) {
  if (view.abort) view.abort.abort();
  const abort = new AbortController();
  view.abort = abort;
  clearErrors();
  $("job-notice").hidden = true;
  Object.assign(view, { id: null, points: [], doc: null, status: null, errors: null });
  view.domain = req.domain ? [...req.domain.x, ...req.domain.y] : view.kind === "solution" ? [0, 1, 0, 1] : null;
  $("stats").hidden = true;
  $("downloads").hidden = true;
  setBusy(true);
  setStatus("submitting…");
  $("curl").textContent = curlLine(req);
  view.request = req;
  updateAddress();
  try {
    const init = { method: "POST", headers: authHeaders(), signal: abort.signal };
    if (view.file && view.kind === "mesh") {
      const form = new FormData();
      form.append("request", JSON.stringify(req));
      form.append("grid", view.file, view.file.name);
      init.body = form;
    } else {
      init.headers["content-type"] = "application/json";
      init.body = JSON.stringify(req);
    }
    const response = await fetch("/v1/jobs", init);
    const body = await response.json();
    if (!response.ok) {
      showProblem(body);
      setStatus(`${response.status} ${body.title || ""}`);
      return;
    }
    view.id = body.id;
    updateAddress();
    setStatus(body.status === "succeeded" ? "from the cache" : "running…");
    await follow(body.id, abort.signal);
  } catch (e) {
    if (e.name !== "AbortError") {
      showError("general", String(e));
      setStatus("failed");
    }
  } finally {
    if (view.abort === abort) {
      view.abort = null;
      setBusy(false);
    }
  }
}

// Follows the job's server-sent events with fetch (an EventSource cannot send a key).
// Follows a job's events until its final one. A stream the server ends before that (a
// client job's, after a quiet spell) is taken up again from the last event seen, as an
// EventSource would.
async function follow(id, signal) {
  const points = view.kind === "mesh" ? "?vertices=true" : "";
  let lastId = null;
  for (;;) {
    const headers = authHeaders();
    if (lastId !== null) headers["last-event-id"] = lastId;
    const response = await fetch(`/v1/jobs/${id}/events${points}`, { headers, signal });
    if (response.status === 204) return; // the final event was seen
    if (!response.ok) {
      showProblem(await response.json());
      return;
    }
    const before = lastId;
    const seen = await readEvents(response, (eventId) => { lastId = eventId; });
    if (seen === "final") return;
    // Nothing new in a whole stream: wait a moment rather than ask again at once.
    if (lastId === before) await new Promise((resolve) => setTimeout(resolve, 1000));
  }
}

// Reads one stream's events, telling `onId` each event's id: "final" once the result or
// error event came, else "ended".
async function readEvents(response, onId) {
  const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
  let buffer = "";
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return "ended";
    buffer += value;
    let end;
    while ((end = buffer.indexOf("\n\n")) >= 0) {
      const block = buffer.slice(0, end);
      buffer = buffer.slice(end + 2);
      let event = "message";
      const data = [];
      for (const line of block.split("\n")) {
        if (line.startsWith("event:")) event = line.slice(6).trim();
        else if (line.startsWith("id:")) onId(line.slice(3).trim());
        else if (line.startsWith("data:")) data.push(line.slice(5).replace(/^ /, ""));
      }
      if (data.length === 0) continue;
      const payload = JSON.parse(data.join("\n"));
      if (event === "progress") progress(payload);
      else if (event === "ask") asking(payload);
      else if (event === "result") {
        await finished(payload);
        return "final";
      } else if (event === "error") {
        showProblem(payload);
        setStatus(payload.title || "failed");
        return "final";
      }
    }
  }
}

function progress(p) {
  if (Array.isArray(p.points)) {
    // A reconnected stream starts again at 0: keep what is new.
    const have = view.points.length / 3;
    const skip = Math.max(0, have - p.first_point) * 3;
    for (let i = skip; i < p.points.length; i++) view.points.push(p.points[i]);
  }
  const worst = view.kind === "solution" ? "estimate" : "worst";
  const done = typeof p.fraction === "number" ? `${Math.floor(100 * p.fraction)}%: ` : "";
  setStatus(`running ${done}${p.vertices} vertices, ${worst} ${fmt(p.worst)}, ${Math.round(p.elapsed_ms)} ms`);
  scheduleDraw();
}

// A client job's batch is out: its caller evaluates F there (the page never does).
function asking(a) {
  const n = a.points.length;
  setStatus(`waiting for the caller: batch ${a.batch}, ${n} point${n === 1 ? "" : "s"} to tell`);
}

// `/?job=ID`: shows a job that exists, running or finished, as its events tell.
export async function openJob(id) {
  // The job's request is not known here (a file cannot travel in an address): say plainly
  // that the form is not it.
  $("job-shown").textContent = id;
  $("job-notice").hidden = false;
  view.id = id;
  view.request = { job: id };
  $("curl").textContent = curlLine(view.request);
  updateAddress();
  setBusy(true);
  try {
    await follow(id, new AbortController().signal);
  } catch (e) {
    showError("general", String(e));
  } finally {
    setBusy(false);
  }
}

// The result event is the job's status and its links; the mesh is fetched once, from there.
async function finished(status) {
  const response = await fetch(status.formats.json, { headers: authHeaders() });
  if (!response.ok) {
    showProblem(await response.json());
    setStatus("failed");
    return;
  }
  const doc = await response.json();
  if (doc.stats.physics && view.kind !== "solution") showTab("solve");
  view.doc = doc;
  view.points = [];
  view.status = status;
  const elapsed = status.elapsed_ms;
  setStatus(`done: ${doc.stats.stop}${elapsed !== undefined && elapsed !== null ? `, ${Math.round(elapsed)} ms` : ", from the cache"}`);
  showStats(doc.stats);
  showDownloads(doc.id);
  if (view.mode === "error") await loadErrors();
  scheduleDraw();
  drawConvergence();
  document.body.dataset.state = "done";
}

function setBusy(busy) {
  $("run").disabled = busy;
  $("solve-run").disabled = busy;
  $("cancel").hidden = !busy;
  // `running`, then `done` (finished) or `failed` (a problem shown), else back to `idle`;
  // the browser test waits on it.
  const state = document.body.dataset.state;
  if (busy) document.body.dataset.state = "running";
  else if (state === "running" || !state) document.body.dataset.state = "idle";
}
export const setStatus = (text) => ($("status").textContent = text);
