// meshfit's page: a client of the public API, like any other.
//
// One way data flows: the form (or the address) makes a request; the request starts a job
// (POST /v1/jobs); the job's events (with ?vertices=true) feed `view`, which the drawings
// read; the final document replaces the growing points. Nothing here computes a mesh.
//
// Each concern is a module (no build step: the browser loads them as they are, and none
// imports one that imports it back); this one reads the address and wires the controls.

import { $, view } from "./state.js";
import { authHeaders, clearErrors, KEY, meshRequest, showError, showTab, updateAddress } from "./form.js";
import { openJob, run, setStatus } from "./jobs.js";
import { loadErrors } from "./downloads.js";
import { frame, scheduleDraw, turn } from "./viewer.js";
import { MAGNET, problemJson } from "./solutions.js";
import { addCircuit, DEVICE, loadLibrary, renderDevice } from "./device.js";
import { drawConvergence } from "./plots.js";
import { uploadDem } from "./terrain.js";

// The problem the device tab's example replaced, given back by the problem tab.
let putAside = null;

// Switches to tab `which` with an empty picture. The device tab opens on |B|, on the
// example device unless the problem in the editor is one (another is put aside, and the
// problem tab gives it back).
function selectTab(which) {
  showTab(which);
  if (which === "device") {
    const p = problemJson();
    if (!p || p.physics !== "magnetostatic") {
      if ($("problem").value.trim()) putAside = $("problem").value;
      $("problem").value = JSON.stringify(DEVICE, null, 2);
    }
    $("solve-colour").value = "b";
    renderDevice(scheduleDraw);
    loadLibrary(() => renderDevice(scheduleDraw));
  }
  if (which === "solve" && putAside !== null) {
    $("problem").value = putAside;
    putAside = null;
  }
  if (which === "solve" || which === "device") {
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

// The value of `key` in the address, decoded as a path is: a `+` stays a plus, which is what a
// person typing ?function=x+y means (URLSearchParams would read a space). The page writes
// spaces as %20 (shareAddress).
function addressValue(key) {
  for (const part of location.search.slice(1).split("&")) {
    const at = part.indexOf("=");
    if (at < 0 || part.slice(0, at) !== key) continue;
    try {
      return decodeURIComponent(part.slice(at + 1));
    } catch (e) {
      return part.slice(at + 1); // a stray `%`: shown as typed, and the API names the column
    }
  }
  return null;
}

// Reads the address: any request field fills the form. True when it names a job to run.
function readAddress() {
  const q = new URLSearchParams(location.search);
  for (const key of ["function", "problem"]) {
    if (q.has(key)) q.set(key, addressValue(key));
  }
  if (["flat", "surface", "error"].includes(q.get("view"))) selectView(q.get("view"));
  if (/^[0-9a-f]{64}$/.test(q.get("job") || "")) return "job";
  if (q.has("problem")) {
    const text = q.get("problem");
    try {
      $("problem").value = JSON.stringify(JSON.parse(text), null, 2);
    } catch (e) {
      $("problem").value = text; // shown as is: the form says it is not JSON
    }
    // A magnetostatic problem is a device: its tab, on |B| unless the address says u.
    const p = problemJson();
    selectTab(p && p.physics === "magnetostatic" ? "device" : "solve");
    if (["u", "b"].includes(q.get("colour"))) $("solve-colour").value = q.get("colour");
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
    if (!$("device-editor").hidden) renderDevice(scheduleDraw);
    view.doc = null;
    view.domain = d;
    scheduleDraw();
  });
}

function wire() {
  $("tab-mesh").addEventListener("click", () => selectTab("mesh"));
  $("tab-solve").addEventListener("click", () => selectTab("solve"));
  $("tab-device").addEventListener("click", () => {
    selectTab("device");
    $("solve-form").requestSubmit();
  });
  $("add-circuit").addEventListener("click", () => addCircuit(scheduleDraw));
  $("tab-terrain").addEventListener("click", () => selectTab("terrain"));
  $("terrain-form").addEventListener("submit", (e) => {
    e.preventDefault();
    clearErrors();
    const file = $("dem-file").files[0];
    if (!file) return showError("dem", "pick a GeoTIFF first");
    uploadDem(file);
  });
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
    if (!$("device-editor").hidden) renderDevice(scheduleDraw);
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
