// meshfit's page: a client of the public API, like any other.
//
// One way data flows: the form (or the address) makes a request; the request starts a job
// (POST /v1/jobs); the job's events (with ?vertices=true) feed `view`, which the drawings
// read; the final document replaces the growing points. Nothing here computes a mesh.
"use strict";

const $ = (id) => document.getElementById(id);
const FORMATS = ["json", "obj", "ply", "stl", "vtu", "msh", "glb", "svg", "png"];
const MAGNET = {
  domain: { x: [0, 0.2], y: [0, 0.1] },
  physics: "magnetostatic",
  regions: [
    { x: [0.04, 0.07], y: [0.035, 0.065], current_density: 2e6 },
    { x: [0.11, 0.16], y: [0.02, 0.08], mu_r: 1000 },
  ],
  max_vertices: 20000,
};

// What is on screen: the job, the vertices streamed so far, then its document.
const view = {
  kind: "mesh", // or "solution"
  id: null,
  domain: null, // [x0, x1, y0, y1]
  points: [], // flat x, y, z while the job runs
  doc: null, // the final mesh document
  status: null, // GET /v1/jobs/{id} once finished
  errors: null, // per-triangle error (from the PLY download), by job id
  mode: "flat", // flat | surface | error
  request: null, // what was sent, for the share link and the curl line
  file: null, // a grid file picked or dropped
  abort: null,
};

// ---- Colours --------------------------------------------------------------------------------

// Viridis at 9 stops, interpolated: the same map as the server's SVG and PNG pictures.
const VIRIDIS = [
  [68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
  [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37],
];
function viridis(t) {
  const s = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 0)) * (VIRIDIS.length - 1);
  const i = Math.min(VIRIDIS.length - 2, Math.floor(s));
  const f = s - i;
  return VIRIDIS[i].map((c, k) => Math.round(c + f * (VIRIDIS[i + 1][k] - c)));
}
const rgb = (c) => `rgb(${c[0]},${c[1]},${c[2]})`;
const fmt = (v) => (typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toPrecision(4)) : String(v));

// ---- Requests -------------------------------------------------------------------------------

// The mesh request the form describes; `bad` collects field errors found before sending.
function meshRequest(bad) {
  const number = (id, name) => {
    const text = $(id).value.trim();
    if (text === "") return undefined;
    const v = Number(text);
    if (!Number.isFinite(v)) bad.push([name, `${name}: not a number: ${text}`]);
    return v;
  };
  const req = {};
  if (!view.file) req.function = $("function").value;
  if (view.file && !$("encoding-field").hidden) req.grid = { encoding: $("encoding").value };
  const d = ["x0", "x1", "y0", "y1"].map((k) => number(k, "domain"));
  if (d.every((v) => v !== undefined)) req.domain = { x: [d[0], d[1]], y: [d[2], d[3]] };
  const n = number("max_vertices", "max_vertices");
  if (n !== undefined) req.max_vertices = n;
  const t = number("tolerance", "tolerance");
  if (t !== undefined) req.tolerance = t;
  req.method = $("method").value;
  req.criterion = $("criterion").value;
  req.quality = true;
  return req;
}

// Reads the address: any request field fills the form. True when it names a job to run.
function readAddress() {
  const q = new URLSearchParams(location.search);
  if (["flat", "surface", "error"].includes(q.get("view"))) selectView(q.get("view"));
  if (/^[0-9a-f]{64}$/.test(q.get("job") || "")) return "job";
  if (q.has("problem")) {
    selectTab("solve");
    const text = q.get("problem");
    try {
      $("problem").value = JSON.stringify(JSON.parse(text), null, 2);
    } catch (e) {
      $("problem").value = text; // shown as is: the form says it is not JSON
    }
    if (q.get("colour") === "b") $("solve-colour").value = "b";
    return "solve";
  }
  let any = false;
  for (const key of ["function", "max_vertices", "tolerance", "method", "criterion"]) {
    if (q.has(key)) {
      $(key).value = q.get(key);
      any = true;
    }
  }
  for (const [key, ids] of [["x", ["x0", "x1"]], ["y", ["y0", "y1"]]]) {
    const parts = (q.get(key) || "").split(",");
    if (parts.length === 2) {
      $(ids[0]).value = parts[0];
      $(ids[1]).value = parts[1];
      any = true;
    }
  }
  return any ? "mesh" : null;
}

function shareAddress(req) {
  const q = new URLSearchParams();
  if (view.file || req.job) {
    // A file cannot travel in an address; the job can, while the server keeps its mesh.
    if (view.id) q.set("job", view.id);
  } else if (view.kind === "solution") {
    q.set("problem", JSON.stringify(req));
  } else {
    if (req.function !== undefined) q.set("function", req.function);
    if (req.domain) {
      q.set("x", req.domain.x.join(","));
      q.set("y", req.domain.y.join(","));
    }
    for (const key of ["max_vertices", "tolerance", "method", "criterion"]) {
      if (req[key] !== undefined) q.set(key, req[key]);
    }
  }
  if (view.mode !== "flat") q.set("view", view.mode);
  if (view.kind === "solution" && $("solve-colour").value === "b") q.set("colour", "b");
  return `${location.pathname}?${q}`;
}

const shellQuote = (s) => `'${s.replace(/'/g, `'\\''`)}'`;
function curlLine(req) {
  const origin = location.origin;
  if (req.job) return `curl -s ${origin}/v1/jobs/${req.job}/mesh`;
  if (view.kind === "solution") {
    return `curl -s ${origin}/v1/solutions -H 'content-type: application/json' \\\n  -d ${shellQuote(JSON.stringify(req))}`;
  }
  if (view.file) {
    return `curl -s ${origin}/v1/meshes -F request=${shellQuote(JSON.stringify(req))} \\\n  -F grid=@${shellQuote(view.file.name)}`;
  }
  return `curl -s ${origin}/v1/meshes -H 'content-type: application/json' \\\n  -d ${shellQuote(JSON.stringify(req))}`;
}

// The address and the share link follow the request and the view shown.
function updateAddress() {
  if (!view.request) return;
  const share = shareAddress(view.request);
  $("share").href = share;
  history.replaceState(null, "", share);
}

// A server with keys needs one on every /v1 request; the page keeps it in this browser.
const KEY = "meshfit-api-key";
function authHeaders() {
  const key = localStorage.getItem(KEY);
  return key ? { authorization: `Bearer ${key}` } : {};
}

// ---- Errors next to their fields ----------------------------------------------------------

function clearErrors() {
  for (const p of document.querySelectorAll(".field-error")) p.textContent = "";
  for (const el of document.querySelectorAll(".invalid")) el.classList.remove("invalid");
}

function showError(field, text) {
  const p = document.querySelector(`.field-error[data-for="${field}"]`) || $("general-error");
  p.textContent = text;
  const input = { function: $("function"), grid: $("grid-file"), problem: $("problem"),
    max_vertices: $("max_vertices"), tolerance: $("tolerance"), domain: $("x0") }[field];
  if (input) input.classList.add("invalid");
  return input;
}

// A problem document (RFC 9457), shown where it says the problem is.
function showProblem(problem) {
  document.body.dataset.state = "failed";
  if (problem.status === 401) $("key-settings").open = true;
  const detail = problem.detail || problem.title || "the request failed";
  if (view.kind === "solution") {
    showError("problem", problem.field ? `${detail}` : detail);
    return;
  }
  const type = problem.type || "";
  let field = "general";
  if (type.endsWith("invalid-expression") || type.endsWith("non-finite-value")) field = view.file ? "grid" : "function";
  else if (type.endsWith("invalid-grid")) field = "grid";
  else if (type.endsWith("invalid-domain")) field = "domain";
  else if (/^(max_vertices|tolerance)\b/.test(detail)) field = detail.startsWith("tolerance") ? "tolerance" : "max_vertices";
  else if (problem.limit && /max_vertices/.test(problem.limit.name || "")) field = "max_vertices";
  const input = showError(field, detail);
  // The column is 1-based, in characters: select the character it names.
  if (field === "function" && Number.isInteger(problem.column) && input) {
    const chars = Array.from(input.value);
    const start = chars.slice(0, problem.column - 1).join("").length;
    const end = start + (chars[problem.column - 1] || "").length;
    input.focus();
    input.setSelectionRange(start, Math.max(end, start + 1));
  }
}

// ---- Running a job ------------------------------------------------------------------------

async function run(req) {
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
async function follow(id, signal) {
  const points = view.kind === "mesh" ? "?vertices=true" : "";
  const response = await fetch(`/v1/jobs/${id}/events${points}`, { headers: authHeaders(), signal });
  if (!response.ok) {
    showProblem(await response.json());
    return;
  }
  const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
  let buffer = "";
  for (;;) {
    const { value, done } = await reader.read();
    if (done) break;
    buffer += value;
    let end;
    while ((end = buffer.indexOf("\n\n")) >= 0) {
      const block = buffer.slice(0, end);
      buffer = buffer.slice(end + 2);
      let event = "message";
      const data = [];
      for (const line of block.split("\n")) {
        if (line.startsWith("event:")) event = line.slice(6).trim();
        else if (line.startsWith("data:")) data.push(line.slice(5).replace(/^ /, ""));
      }
      if (data.length === 0) continue;
      const payload = JSON.parse(data.join("\n"));
      if (event === "progress") progress(payload);
      else if (event === "result") await finished(payload);
      else if (event === "error") {
        showProblem(payload);
        setStatus(payload.title || "failed");
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
  setStatus(`running: ${p.vertices} vertices, ${worst} ${fmt(p.worst)}, ${Math.round(p.elapsed_ms)} ms`);
  scheduleDraw();
}

// `/?job=ID`: shows a job that exists, running or finished, as its events tell.
async function openJob(id) {
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

async function finished(doc) {
  if (doc.stats.physics && view.kind !== "solution") showTab("solve");
  view.doc = doc;
  view.points = [];
  const response = await fetch(`/v1/jobs/${doc.id}`, { headers: authHeaders() });
  view.status = response.ok ? await response.json() : null;
  const elapsed = view.status && view.status.elapsed_ms;
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
const setStatus = (text) => ($("status").textContent = text);

// ---- Stats and downloads ------------------------------------------------------------------

function showStats(s) {
  const q = s.quality || {};
  const rows = view.kind === "solution"
    ? [["vertices", s.vertices], ["triangles", s.triangles], ["unknowns", s.unknowns], ["solves", s.solves],
      ["estimate", s.estimate], ["energy", s.energy], ["coenergy", s.coenergy], ["flips", s.flips], ["stop", s.stop],
      ["delaunay", s.delaunay], ["constrained_edges", s.constrained_edges],
      // One row per region: the force on everything inside it, [fx, fy] in N/m.
      ...(s.regions || []).map((r, i) => [`force_${i}`, r.force])]
    : [["vertices", s.vertices], ["triangles", s.triangles], ["variation", s.variation],
      ["max_triangle_error", s.max_triangle_error], ["max_error", q.max_error], ["rms_error", q.rms_error],
      ["min_angle_deg", q.min_angle_deg], ["evaluations", s.evaluations], ["flips", s.flips], ["stop", s.stop],
      ["delaunay", s.delaunay]];
  const labels = { variation: "V_n", max_triangle_error: "worst e(T)", max_error: "E_n estimate",
    rms_error: "RMS error", min_angle_deg: "smallest angle (°)", constrained_edges: "edges on region sides" };
  (s.regions || []).forEach((_, i) => (labels[`force_${i}`] = `force on region ${i} (N/m)`));
  const body = $("stats").tBodies[0];
  body.replaceChildren();
  for (const [key, value] of rows) {
    if (value === undefined || value === null) continue;
    const tr = body.insertRow();
    const th = document.createElement("th");
    th.textContent = labels[key] || key;
    tr.append(th);
    const td = tr.insertCell();
    td.textContent = Array.isArray(value) ? value.map(fmt).join(", ") : fmt(value);
    td.dataset.stat = key;
    td.dataset.value = JSON.stringify(value);
  }
  const elapsed = view.status && view.status.elapsed_ms;
  if (elapsed !== undefined && elapsed !== null) {
    const tr = body.insertRow();
    tr.innerHTML = "<th>engine time (ms)</th>";
    tr.insertCell().textContent = fmt(elapsed);
  }
  $("stats").hidden = false;
}

function showDownloads(id) {
  const links = $("download-links");
  links.replaceChildren();
  for (const format of FORMATS) {
    const a = document.createElement("a");
    a.href = `/v1/jobs/${id}/mesh?format=${format}`;
    a.download = `meshfit-${id.slice(0, 8)}.${format}`;
    a.textContent = format.toUpperCase();
    a.dataset.format = format;
    // A link cannot send a key: with one, the file is fetched and saved from memory.
    a.addEventListener("click", async (e) => {
      const headers = authHeaders();
      if (!headers.authorization) return;
      e.preventDefault();
      const response = await fetch(a.href, { headers });
      if (!response.ok) return showProblem(await response.json());
      const url = URL.createObjectURL(await response.blob());
      const save = Object.assign(document.createElement("a"), { href: url, download: a.download });
      save.click();
      setTimeout(() => URL.revokeObjectURL(url), 10000);
    });
    links.append(a);
  }
  $("downloads").hidden = false;
}

// ---- Drawing: the plane -------------------------------------------------------------------

let drawPending = false;
function scheduleDraw() {
  if (drawPending) return;
  drawPending = true;
  requestAnimationFrame(() => {
    drawPending = false;
    draw();
  });
}

function draw() {
  if (view.mode === "surface") drawSurface();
  else drawFlat();
}

// Maps the domain onto the canvas, keeping its aspect ratio, with room for the axes' labels
// on the left and below.
const AXIS_LEFT = 64, AXIS_BELOW = 30;
function frame(canvas, d) {
  const pad = 12;
  const [w, h] = [canvas.width - 2 * pad - AXIS_LEFT, canvas.height - 2 * pad - AXIS_BELOW];
  const scale = Math.min(w / (d[1] - d[0] || 1), h / (d[3] - d[2] || 1));
  const ox = pad + AXIS_LEFT + (w - scale * (d[1] - d[0])) / 2;
  const oy = pad + AXIS_BELOW + (h - scale * (d[3] - d[2])) / 2;
  return {
    x: (x) => ox + (x - d[0]) * scale,
    y: (y) => canvas.height - (oy + (y - d[2]) * scale),
    back: (px, py) => [d[0] + (px - ox) / scale, d[2] + (canvas.height - py - oy) / scale],
    rect: [ox, canvas.height - oy - scale * (d[3] - d[2]), scale * (d[1] - d[0]), scale * (d[3] - d[2])],
  };
}

// Round numbers from lo to hi, about five, 1, 2 or 5 × 10^k apart, labelled to the step's
// precision: the rule of the svg and png pictures (output/picture.rs).
function ticks(lo, hi) {
  const raw = (hi - lo) / 5;
  if (!(raw > 0 && Number.isFinite(raw))) return [];
  const magnitude = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((m) => m * magnitude).find((s) => s >= raw) || raw;
  const decimals = Math.max(0, -Math.floor(Math.log10(step)));
  const out = [];
  for (let k = Math.ceil(lo / step - 1e-9); k <= Math.floor(hi / step + 1e-9); k++) {
    const v = k * step;
    out.push([v, (v + 0).toFixed(decimals)]);
  }
  return out;
}

// Tick marks and labels along the plot's bottom (x) and left side (y).
function drawAxes(g, f, d) {
  const [left, top, width, height] = f.rect;
  g.strokeStyle = "#4a5160";
  g.fillStyle = "#4a5160";
  g.lineWidth = 1;
  g.font = "12px system-ui, sans-serif";
  g.beginPath();
  g.textAlign = "center";
  g.textBaseline = "top";
  const [xs, ys] = [ticks(d[0], d[1]), ticks(d[2], d[3])];
  // The labels drawn, for the browser test to read.
  g.canvas.dataset.xTicks = xs.map(([, label]) => label).join(" ");
  g.canvas.dataset.yTicks = ys.map(([, label]) => label).join(" ");
  for (const [x, label] of xs) {
    const at = f.x(x);
    g.moveTo(at, top + height);
    g.lineTo(at, top + height + 5);
    g.fillText(label, at, top + height + 8);
  }
  g.textAlign = "right";
  g.textBaseline = "middle";
  for (const [y, label] of ys) {
    const at = f.y(y);
    g.moveTo(left, at);
    g.lineTo(left - 5, at);
    g.fillText(label, left - 8, at);
  }
  g.stroke();
}

// The colour bar under the picture: viridis from lo to hi, with what it measures; `null` hides
// it (nothing coloured).
function colourBar(lo, hi, what) {
  const bar = $("colourbar");
  bar.hidden = what === null;
  if (what === null) return;
  const stops = Array.from({ length: 11 }, (_, i) => rgb(viridis(i / 10)));
  bar.querySelector(".scale").style.background = `linear-gradient(to right, ${stops.join(", ")})`;
  bar.querySelector(".lo").textContent = fmt(lo);
  bar.querySelector(".hi").textContent = fmt(hi);
  bar.querySelector(".what").textContent = what;
}

function domainOf(vertices) {
  let d = [Infinity, -Infinity, Infinity, -Infinity];
  for (const [x, y] of vertices) d = [Math.min(d[0], x), Math.max(d[1], x), Math.min(d[2], y), Math.max(d[3], y)];
  return d;
}

function range(values) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) {
    if (v < lo) lo = v;
    if (v > hi) hi = v;
  }
  return lo <= hi ? [lo, hi] : [0, 1];
}

// Per-triangle values to colour by, and their label.
function triangleValues() {
  const doc = view.doc;
  const V = doc.vertices;
  if (view.mode === "error") {
    const e = view.errors && view.errors.id === doc.id ? view.errors.values : null;
    if (!e || e.length !== doc.triangles.length) return null;
    // Logarithmic: errors span decades.
    const floor = Math.max(1e-300, range(e.filter((v) => v > 0))[0]);
    return { values: e.map((v) => Math.log10(Math.max(v, floor))), label: "log10 error per triangle" };
  }
  if (view.kind === "solution" && $("solve-colour").value === "b" && doc.flux_density) {
    return { values: doc.flux_density.map(([bx, by]) => Math.hypot(bx, by)), label: "|B| (T)" };
  }
  const label = view.kind === "solution" ? "u" : "F";
  return { values: doc.triangles.map(([a, b, c]) => (V[a][2] + V[b][2] + V[c][2]) / 3), label };
}

// The picture takes the domain's shape, within 3:8 and 8:8.
function fitHeight(canvas, d) {
  const aspect = (d[3] - d[2]) / (d[1] - d[0]);
  const height = Math.round(canvas.width * Math.min(1, Math.max(0.375, Number.isFinite(aspect) ? aspect : 1)));
  if (canvas.height !== height) canvas.height = height;
}

function drawFlat() {
  const canvas = $("flat");
  const g = canvas.getContext("2d");
  g.fillStyle = "#ffffff";
  g.fillRect(0, 0, canvas.width, canvas.height);
  const d = view.doc ? domainOf(view.doc.vertices) : view.domain;
  if (!d) return;
  fitHeight(canvas, d);
  const f = frame(canvas, d);
  g.strokeStyle = "#9aa1ad";
  g.lineWidth = 1;
  g.strokeRect(...f.rect);
  drawAxes(g, f, d);
  if (!view.doc) {
    colourBar(0, 0, null);
    drawPoints(g, f);
    if (view.kind === "solution") drawRegions(g, f);
    return;
  }
  const tv = triangleValues();
  if (!tv) {
    const loaded = view.errors && view.errors.id === view.doc.id;
    colourBar(0, 0, null);
    legend(loaded ? "no per-triangle error for this mesh (criterion variation)" : "loading the per-triangle errors…");
    return;
  }
  const V = view.doc.vertices;
  const T = view.doc.triangles;
  const [lo, hi] = range(tv.values);
  // One path per colour: tens of thousands of triangles fill in a few calls.
  const buckets = 64;
  const paths = Array.from({ length: buckets }, () => new Path2D());
  T.forEach(([a, b, c], t) => {
    const k = Math.min(buckets - 1, Math.floor(((tv.values[t] - lo) / (hi - lo || 1)) * buckets));
    const p = paths[k];
    p.moveTo(f.x(V[a][0]), f.y(V[a][1]));
    p.lineTo(f.x(V[b][0]), f.y(V[b][1]));
    p.lineTo(f.x(V[c][0]), f.y(V[c][1]));
    p.closePath();
  });
  paths.forEach((p, k) => {
    const colour = rgb(viridis((k + 0.5) / buckets));
    g.fillStyle = colour;
    g.fill(p);
    // Hairline strokes in the fill colour close the seams antialiasing leaves.
    g.strokeStyle = colour;
    g.lineWidth = 0.6;
    g.stroke(p);
  });
  if (T.length <= 60000) {
    const edges = new Path2D();
    for (const [a, b, c] of T) {
      edges.moveTo(f.x(V[a][0]), f.y(V[a][1]));
      edges.lineTo(f.x(V[b][0]), f.y(V[b][1]));
      edges.lineTo(f.x(V[c][0]), f.y(V[c][1]));
      edges.closePath();
    }
    g.strokeStyle = "rgba(20, 24, 32, 0.35)";
    g.lineWidth = T.length > 8000 ? 0.3 : 0.6;
    g.stroke(edges);
  }
  if (view.kind === "solution" && view.doc.flux_density && $("arrows").checked) drawArrows(g, f);
  // The error view colours log10 of the errors: its bar is labelled with the errors themselves.
  const logScale = view.mode === "error";
  colourBar(logScale ? 10 ** lo : lo, logScale ? 10 ** hi : hi, logScale ? "error per triangle (log scale)" : tv.label);
  legend(`${tv.label}: ${fmt(lo)} … ${fmt(hi)}, ${V.length} vertices, ${T.length} triangles`, tv.label);
}

// The line under the picture; `label` names what the finished picture is coloured by.
function legend(text, label) {
  const el = $("legend");
  el.textContent = text;
  if (label) {
    el.dataset.mode = view.mode;
    el.dataset.label = label;
  } else {
    delete el.dataset.mode;
    delete el.dataset.label;
  }
}

// The vertices streamed so far, coloured by their value.
function drawPoints(g, f) {
  const P = view.points;
  if (P.length === 0) return;
  let lo = Infinity, hi = -Infinity;
  for (let i = 2; i < P.length; i += 3) {
    lo = Math.min(lo, P[i]);
    hi = Math.max(hi, P[i]);
  }
  const size = P.length / 3 > 20000 ? 1.5 : 2.5;
  for (let i = 0; i < P.length; i += 3) {
    g.fillStyle = rgb(viridis((P[i + 2] - lo) / (hi - lo || 1)));
    g.fillRect(f.x(P[i]) - size / 2, f.y(P[i + 1]) - size / 2, size, size);
  }
  colourBar(lo, hi, "F at the vertices so far");
  legend(`${P.length / 3} vertices so far: F ${fmt(lo)} … ${fmt(hi)}`);
}

// ---- Drawing: the surface (WebGL) ---------------------------------------------------------

const turn = { yaw: -0.6, pitch: 0.9 };
let gl = null;

function drawSurface() {
  const canvas = $("surface");
  if (!view.doc) return;
  gl = gl || canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) {
    legend("this browser has no WebGL");
    return;
  }
  const program = surfaceProgram(gl);
  const V = view.doc.vertices;
  const T = view.doc.triangles;
  const d = domainOf(V);
  const [zlo, zhi] = range(V.map((v) => v[2]));
  const span = Math.max(d[1] - d[0], d[3] - d[2]) || 1;
  // Flat shading: three vertices per triangle, each with the triangle's normal.
  const pos = new Float32Array(T.length * 9);
  const col = new Float32Array(T.length * 9);
  const nor = new Float32Array(T.length * 9);
  const place = (v) => [
    (2 * (v[0] - (d[0] + d[1]) / 2)) / span,
    (2 * (v[1] - (d[2] + d[3]) / 2)) / span,
    ((v[2] - zlo) / (zhi - zlo || 1) - 0.5) * 0.8,
  ];
  T.forEach((tri, t) => {
    const p = tri.map((i) => place(V[i]));
    const u = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
    const w = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
    const n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
    const len = Math.hypot(...n) || 1;
    for (let k = 0; k < 3; k++) {
      const c = viridis((V[tri[k]][2] - zlo) / (zhi - zlo || 1));
      for (let m = 0; m < 3; m++) {
        pos[9 * t + 3 * k + m] = p[k][m];
        nor[9 * t + 3 * k + m] = n[m] / len;
        col[9 * t + 3 * k + m] = c[m] / 255;
      }
    }
  });
  const bind = (name, data) => {
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    const at = gl.getAttribLocation(program, name);
    gl.enableVertexAttribArray(at);
    gl.vertexAttribPointer(at, 3, gl.FLOAT, false, 0, 0);
    return buffer;
  };
  const buffers = [bind("position", pos), bind("normal", nor), bind("colour", col)];
  gl.viewport(0, 0, canvas.width, canvas.height);
  gl.clearColor(1, 1, 1, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  gl.uniformMatrix4fv(gl.getUniformLocation(program, "turn"), false, rotation(turn.yaw, turn.pitch));
  gl.drawArrays(gl.TRIANGLES, 0, T.length * 3);
  buffers.forEach((b) => gl.deleteBuffer(b));
  colourBar(zlo, zhi, view.kind === "solution" ? "u" : "F");
  legend(`surface of ${V.length} vertices; drag to turn it`, "surface");
}

function surfaceProgram(gl) {
  if (gl.meshfitProgram) return gl.meshfitProgram;
  const shader = (type, source) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    return s;
  };
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, `
    attribute vec3 position; attribute vec3 normal; attribute vec3 colour;
    uniform mat4 turn; varying vec3 shade;
    void main() {
      vec4 p = turn * vec4(position, 1.0);
      gl_Position = vec4(p.xy * 0.62, -p.z * 0.3, 1.0);
      float light = abs(dot(normalize((turn * vec4(normal, 0.0)).xyz), normalize(vec3(0.3, 0.4, 1.0))));
      shade = colour * (0.35 + 0.65 * light);
    }`));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, `
    precision mediump float; varying vec3 shade;
    void main() { gl_FragColor = vec4(shade, 1.0); }`));
  gl.linkProgram(program);
  gl.useProgram(program);
  gl.meshfitProgram = program;
  return program;
}

// Column-major: a turn about z by `yaw`, then a tilt about x by `pitch`.
function rotation(yaw, pitch) {
  const [cy, sy, cp, sp] = [Math.cos(yaw), Math.sin(yaw), Math.cos(pitch), Math.sin(pitch)];
  return new Float32Array([
    cy, sy * cp, sy * sp, 0,
    -sy, cy * cp, cy * sp, 0,
    0, -sp, cp, 0,
    0, 0, 0, 1,
  ]);
}

// ---- The error view: per-triangle error from the PLY download -----------------------------

async function loadErrors() {
  const doc = view.doc;
  if (!doc || (view.errors && view.errors.id === doc.id)) return;
  const response = await fetch(`/v1/jobs/${doc.id}/mesh?format=ply`, { headers: authHeaders() });
  const values = response.ok ? plyErrors(await response.arrayBuffer()) : null;
  view.errors = { id: doc.id, values: values || [] };
}

// The `error` property of each face of a binary little-endian PLY, or null.
function plyErrors(buffer) {
  const bytes = new Uint8Array(buffer);
  const head = new TextDecoder().decode(bytes.subarray(0, Math.min(bytes.length, 1024)));
  const end = head.indexOf("end_header\n");
  if (end < 0 || !/property double error/.test(head)) return null;
  const vertices = Number(/element vertex (\d+)/.exec(head)[1]);
  const faces = Number(/element face (\d+)/.exec(head)[1]);
  const data = new DataView(buffer, end + "end_header\n".length);
  let at = vertices * 24;
  const errors = new Array(faces);
  for (let f = 0; f < faces; f++) {
    const n = data.getUint8(at);
    at += 1 + 4 * n;
    errors[f] = data.getFloat64(at, true);
    at += 8;
  }
  return errors;
}

// ---- Boundary value problems --------------------------------------------------------------

function problemJson() {
  try {
    return JSON.parse($("problem").value);
  } catch (e) {
    return null;
  }
}

function drawRegions(g, f) {
  const p = problemJson();
  if (!p || !Array.isArray(p.regions)) return;
  for (const r of p.regions) {
    // A rectangle's corners or a polygon's, in picture coordinates.
    const corners = Array.isArray(r.polygon)
      ? r.polygon
      : Array.isArray(r.x) && Array.isArray(r.y)
        ? [[r.x[0], r.y[0]], [r.x[1], r.y[0]], [r.x[1], r.y[1]], [r.x[0], r.y[1]]]
        : null;
    if (!corners || corners.length < 3) continue;
    const current = r.current_density || r.current;
    g.fillStyle = current ? "rgba(214, 96, 77, 0.35)" : r.mu_r || r.bh || r.magnetization ? "rgba(90, 110, 140, 0.35)" : "rgba(47, 95, 208, 0.25)";
    g.beginPath();
    corners.forEach(([x, y], i) => (i ? g.lineTo(f.x(x), f.y(y)) : g.moveTo(f.x(x), f.y(y))));
    g.closePath();
    g.fill();
    g.strokeStyle = "#394150";
    g.stroke();
    g.fillStyle = "#1d2330";
    g.font = "13px system-ui, sans-serif";
    const label = r.current_density ? `J ${fmt(r.current_density)}` : r.current ? `I ${fmt(r.current)} A`
      : r.magnetization ? `M ${r.magnetization.map(fmt).join(", ")}` : r.bh ? "B–H" : r.mu_r ? `μr ${fmt(r.mu_r)}` : `k ${fmt(r.k)} f ${fmt(r.f)}`;
    const left = Math.min(...corners.map(([x]) => f.x(x)));
    const top = Math.min(...corners.map(([, y]) => f.y(y)));
    g.fillText(label, left + 4, top + 15);
  }
}

// B on a coarse grid of the picture: the arrow of the first triangle whose centroid falls in
// each cell, its length by |B| relative to the largest.
function drawArrows(g, f) {
  const V = view.doc.vertices;
  const B = view.doc.flux_density;
  const cells = 28;
  const [x, y, w, h] = f.rect;
  const seen = new Map();
  view.doc.triangles.forEach(([a, b, c], t) => {
    const px = (f.x(V[a][0]) + f.x(V[b][0]) + f.x(V[c][0])) / 3;
    const py = (f.y(V[a][1]) + f.y(V[b][1]) + f.y(V[c][1])) / 3;
    const key = `${Math.floor(((px - x) / w) * cells)},${Math.floor(((py - y) / h) * cells)}`;
    if (!seen.has(key)) seen.set(key, [px, py, t]);
  });
  const max = Math.max(...B.map(([bx, by]) => Math.hypot(bx, by))) || 1;
  const step = Math.min(w, h) / cells;
  g.strokeStyle = "#ffffff";
  g.fillStyle = "#ffffff";
  g.lineWidth = 1.2;
  for (const [px, py, t] of seen.values()) {
    const [bx, by] = B[t];
    const m = Math.hypot(bx, by) / max;
    if (m < 0.02) continue;
    const len = step * (0.35 + 0.6 * Math.sqrt(m));
    const [ux, uy] = [bx / Math.hypot(bx, by), -by / Math.hypot(bx, by)];
    const [tx, ty] = [px + (ux * len) / 2, py + (uy * len) / 2];
    g.beginPath();
    g.moveTo(px - (ux * len) / 2, py - (uy * len) / 2);
    g.lineTo(tx, ty);
    g.moveTo(tx - ux * 4 - uy * 2.5, ty - uy * 4 + ux * 2.5);
    g.lineTo(tx, ty);
    g.lineTo(tx - ux * 4 + uy * 2.5, ty - uy * 4 - ux * 2.5);
    g.stroke();
  }
}

// Drag on the picture to add a region to the problem.
function regionDrag() {
  const canvas = $("flat");
  let start = null;
  const at = (e) => {
    const r = canvas.getBoundingClientRect();
    return [((e.clientX - r.left) / r.width) * canvas.width, ((e.clientY - r.top) / r.height) * canvas.height];
  };
  canvas.addEventListener("pointerdown", (e) => {
    if (view.kind !== "solution") return;
    start = at(e);
  });
  canvas.addEventListener("pointerup", (e) => {
    if (!start || view.kind !== "solution") return;
    const p = problemJson();
    const end = at(e);
    const d = p && p.domain ? [...p.domain.x, ...p.domain.y] : [0, 1, 0, 1];
    const f = frame(canvas, d);
    const [a, b] = [f.back(...start), f.back(...end)];
    start = null;
    if (!p) return;
    const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
    const round = (v) => Number(v.toPrecision(3));
    const x = [clamp(Math.min(a[0], b[0]), d[0], d[1]), clamp(Math.max(a[0], b[0]), d[0], d[1])].map(round);
    const y = [clamp(Math.min(a[1], b[1]), d[2], d[3]), clamp(Math.max(a[1], b[1]), d[2], d[3])].map(round);
    if (x[1] - x[0] <= 0 || y[1] - y[0] <= 0) return;
    const region = { x, y };
    if ((p.physics || "poisson") === "magnetostatic") Object.assign(region, e.shiftKey ? { current_density: 2e6 } : { mu_r: 1000 });
    else region.k = 10;
    p.regions = [...(p.regions || []), region];
    $("problem").value = JSON.stringify(p, null, 2);
    view.doc = null;
    view.domain = d;
    scheduleDraw();
  });
}

// ---- Convergence --------------------------------------------------------------------------

function drawConvergence() {
  const canvas = $("convergence");
  const g = canvas.getContext("2d");
  g.fillStyle = "#ffffff";
  g.fillRect(0, 0, canvas.width, canvas.height);
  const s = view.doc && view.doc.stats;
  if (!s || !Array.isArray(s.history) || s.history.length === 0) return;
  const h = s.history;
  const series = view.kind === "solution"
    ? [["estimate", "#2f5fd0"], ["l2_error", "#d6604d"], ["max_nodal_error", "#4daf4a"]]
    : [["variation", "#2f5fd0"], ["worst", "#d6604d"]];
  const names = { variation: "V_n", worst: s.max_triangle_error !== undefined ? "worst e(T)" : "worst |zi − zj|",
    estimate: "estimate", l2_error: "L2 error", max_nodal_error: "max nodal error" };
  const lines = series
    .map(([key, colour]) => [key, colour, h.filter((p) => p[key] > 0).map((p) => [p.vertices, p[key]])])
    .filter(([, , pts]) => pts.length > 0);
  if (lines.length === 0) return;
  const all = lines.flatMap(([, , pts]) => pts);
  const [nlo, nhi] = range(all.map((p) => Math.log10(p[0])));
  const [vlo, vhi] = range(all.map((p) => Math.log10(p[1])));
  const [x0, x1, y0, y1] = [Math.floor(nlo), Math.ceil(nhi) || 1, Math.floor(vlo), Math.ceil(vhi)];
  const pad = { l: 56, r: 16, t: 14, b: 36 };
  const X = (v) => pad.l + ((Math.log10(v) - x0) / (x1 - x0 || 1)) * (canvas.width - pad.l - pad.r);
  const Y = (v) => canvas.height - pad.b - ((Math.log10(v) - y0) / (y1 - y0 || 1)) * (canvas.height - pad.t - pad.b);
  g.font = "12px system-ui, sans-serif";
  g.strokeStyle = "#e3e6eb";
  g.fillStyle = "#5b6474";
  g.lineWidth = 1;
  for (let k = x0; k <= x1; k++) {
    const x = X(10 ** k);
    g.beginPath();
    g.moveTo(x, pad.t);
    g.lineTo(x, canvas.height - pad.b);
    g.stroke();
    g.fillText(`1e${k}`, x - 10, canvas.height - pad.b + 16);
  }
  for (let k = y0; k <= y1; k++) {
    const y = Y(10 ** k);
    g.beginPath();
    g.moveTo(pad.l, y);
    g.lineTo(canvas.width - pad.r, y);
    g.stroke();
    g.fillText(`1e${k}`, 8, y + 4);
  }
  g.fillText("vertices n", canvas.width / 2 - 24, canvas.height - 6);
  lines.forEach(([key, colour, pts], i) => {
    g.strokeStyle = colour;
    g.fillStyle = colour;
    g.lineWidth = 2;
    g.beginPath();
    pts.forEach(([n, v], k) => (k ? g.lineTo(X(n), Y(v)) : g.moveTo(X(n), Y(v))));
    g.stroke();
    for (const [n, v] of pts) g.fillRect(X(n) - 2, Y(v) - 2, 4, 4);
    g.fillText(names[key], canvas.width - pad.r - 130, pad.t + 14 + 16 * i);
  });
}

// ---- Wiring -------------------------------------------------------------------------------

// Shows tab `which` ("mesh" or "solve") and its form.
function showTab(which) {
  view.kind = which === "solve" ? "solution" : "mesh";
  $("tab-mesh").setAttribute("aria-selected", String(which !== "solve"));
  $("tab-solve").setAttribute("aria-selected", String(which === "solve"));
  $("mesh-form").hidden = which === "solve";
  $("solve-form").hidden = which !== "solve";
}

// Switches to tab `which` with an empty picture.
function selectTab(which) {
  showTab(which);
  if (which === "solve") {
    if (!$("problem").value) $("problem").value = JSON.stringify(MAGNET, null, 2);
    const p = problemJson();
    view.domain = p && p.domain ? [...p.domain.x, ...p.domain.y] : [0, 1, 0, 1];
  }
  view.doc = null;
  view.points = [];
  scheduleDraw();
  drawConvergence();
}

function selectView(mode) {
  view.mode = mode;
  for (const b of document.querySelectorAll(".view")) b.setAttribute("aria-selected", String(b.dataset.view === mode));
  $("flat").hidden = mode === "surface";
  $("surface").hidden = mode !== "surface";
  if (mode === "error") loadErrors().then(scheduleDraw);
  updateAddress();
  scheduleDraw();
}

// Byte 25 of a PNG is its IHDR colour type: 2 is RGB, 6 RGBA, which a heightmap can only be
// as a web-map elevation tile, whose encoding the request must name.
async function isColourPng(file) {
  const head = new Uint8Array(await file.slice(0, 26).arrayBuffer());
  const png = [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a].every((b, k) => head[k] === b);
  return png && head.length === 26 && (head[25] === 2 || head[25] === 6);
}

function setFile(file) {
  view.file = file || null;
  $("encoding-field").hidden = true;
  if (file) isColourPng(file).then((colour) => ($("encoding-field").hidden = !colour || view.file !== file));
  $("drop-text").textContent = file ? `${file.name} (${Math.round(file.size / 1024)} KiB)` : "Drop a heightmap here or pick one";
  $("grid-clear").hidden = !file;
  $("function").disabled = Boolean(file);
  // A grid's domain defaults to its nodes, [0, nx-1] x [0, ny-1], or a GeoTIFF's own.
  ["x0", "x1", "y0", "y1"].forEach((id, k) => {
    $(id).value = file ? "" : ["0", "1", "0", "1"][k];
    $(id).placeholder = file ? "from the file" : "";
  });
  if (!file) $("grid-file").value = "";
}

function wire() {
  $("tab-mesh").addEventListener("click", () => selectTab("mesh"));
  $("tab-solve").addEventListener("click", () => selectTab("solve"));
  for (const b of document.querySelectorAll(".view")) b.addEventListener("click", () => selectView(b.dataset.view));
  $("mesh-form").addEventListener("submit", (e) => {
    e.preventDefault();
    const bad = [];
    const req = meshRequest(bad);
    clearErrors();
    if (bad.length) return bad.forEach(([field, text]) => showError(field, text));
    run(req);
  });
  $("solve-form").addEventListener("submit", (e) => {
    e.preventDefault();
    clearErrors();
    const p = problemJson();
    if (!p || typeof p !== "object" || Array.isArray(p)) return showError("problem", "not a JSON object");
    if (!p.physics) p.physics = "poisson";
    run(p);
  });
  // A fresh page: the form's defaults, nothing shown.
  $("job-new").addEventListener("click", () => location.assign("/"));
  $("cancel").addEventListener("click", async () => {
    if (view.id) await fetch(`/v1/jobs/${view.id}`, { method: "DELETE", headers: authHeaders() });
    if (view.abort) view.abort.abort();
    setStatus("cancelled");
  });
  $("grid-file").addEventListener("change", () => setFile($("grid-file").files[0]));
  $("grid-clear").addEventListener("click", () => setFile(null));
  const drop = $("drop");
  drop.addEventListener("dragover", (e) => {
    e.preventDefault();
    drop.classList.add("over");
  });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    e.preventDefault();
    drop.classList.remove("over");
    if (e.dataTransfer.files.length) setFile(e.dataTransfer.files[0]);
  });
  $("problem").addEventListener("input", () => {
    const p = problemJson();
    if (p && p.domain && !view.doc) {
      view.domain = [...p.domain.x, ...p.domain.y];
      scheduleDraw();
    }
  });
  $("solve-colour").addEventListener("change", () => {
    updateAddress();
    scheduleDraw();
  });
  $("arrows").addEventListener("change", scheduleDraw);
  regionDrag();
  $("api-key").value = localStorage.getItem(KEY) || "";
  $("api-key").addEventListener("change", () => {
    const key = $("api-key").value.trim();
    if (key) localStorage.setItem(KEY, key);
    else localStorage.removeItem(KEY);
  });
  const surface = $("surface");
  let drag = null;
  surface.addEventListener("pointerdown", (e) => {
    drag = [e.clientX, e.clientY];
    surface.setPointerCapture(e.pointerId);
  });
  surface.addEventListener("pointermove", (e) => {
    if (!drag) return;
    turn.yaw += (e.clientX - drag[0]) * 0.01;
    turn.pitch = Math.min(1.5, Math.max(0, turn.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY];
    scheduleDraw();
  });
  surface.addEventListener("pointerup", () => (drag = null));
}

wire();
const asked = readAddress();
if (asked === "job") {
  openJob(new URLSearchParams(location.search).get("job"));
} else if (asked === "solve") {
  $("solve-form").requestSubmit();
} else if (asked === "mesh") {
  $("mesh-form").requestSubmit();
} else {
  // A first visit shows the example at once: a picture and a plot say more than a form.
  $("mesh-form").requestSubmit();
}
