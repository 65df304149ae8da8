// Stats and downloads of a finished job, and the per-triangle error read back from its PLY.

import { $, view } from "./state.js";
import { fmt } from "./colours.js";
import { authHeaders, showProblem } from "./form.js";

// The formats the server encodes, in its order (a test of the server checks this list).
const FORMATS = ["json", "obj", "ply", "stl", "vtu", "msh", "glb", "svg", "png"];

export function showStats(s) {
  const q = s.quality || {};
  const rows = view.kind === "solution"
    ? [["vertices", s.vertices], ["triangles", s.triangles], ["unknowns", s.unknowns], ["solves", s.solves],
      ["estimate", s.estimate], ["energy", s.energy], ["coenergy", s.coenergy], ["flips", s.flips], ["stop", s.stop],
      ["delaunay", s.delaunay], ["constrained_edges", s.constrained_edges],
      // One row per region: the force on everything inside it, [fx, fy]; one per circuit: its
      // apparent and incremental inductance.
      ...(s.regions || []).map((r, i) => [`force_${i}`, r.force]),
      ...Object.entries(s.circuits || {}).map(([name, c]) => [`circuit_${name}`, [c.inductance, c.incremental_inductance]])]
    : [["vertices", s.vertices], ["triangles", s.triangles], ["variation", s.variation],
      ["max_triangle_error", s.max_triangle_error], ["max_error", q.max_error], ["rms_error", q.rms_error],
      ["min_angle_deg", q.min_angle_deg], ["evaluations", s.evaluations], ["flips", s.flips], ["stop", s.stop],
      ["delaunay", s.delaunay]];
  const labels = { variation: "V_n", max_triangle_error: "worst e(T)", max_error: "E_n estimate",
    rms_error: "RMS error", min_angle_deg: "smallest angle (°)", constrained_edges: "edges on region sides" };
  // With a depth the figures are the device's totals, else per metre of depth.
  const [newtons, henries] = s.depth ? ["N", "H"] : ["N/m", "H/m"];
  (s.regions || []).forEach((r, i) => (labels[`force_${i}`] = `force on ${r.name || `region ${i}`} (${newtons})`));
  for (const name of Object.keys(s.circuits || {})) labels[`circuit_${name}`] = `inductance of ${name}, apparent, incremental (${henries})`;
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

export function showDownloads(id) {
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


export async function loadErrors() {
  const doc = view.doc;
  if (!doc || (view.errors && view.errors.id === doc.id)) return;
  const response = await fetch(`/v1/jobs/${doc.id}/mesh?format=ply`, { headers: authHeaders() });
  const values = response.ok ? plyErrors(await response.arrayBuffer()) : null;
  view.errors = { id: doc.id, values: values || [] };
}

// The PLY layout read here, as the server writes it (a test of the server checks both agree):
// 3 doubles a vertex, then per face a uchar count, that many ints and a double.
const PLY_VERTEX = "property double x\nproperty double y\nproperty double z\n";
const PLY_FACE = "property list uchar int vertex_indices\nproperty double error\n";

// The `error` property of each face of a binary little-endian PLY, or null.
function plyErrors(buffer) {
  const bytes = new Uint8Array(buffer);
  const head = new TextDecoder().decode(bytes.subarray(0, Math.min(bytes.length, 1024)));
  const end = head.indexOf("end_header\n");
  if (end < 0 || !head.includes(PLY_VERTEX) || !head.includes(PLY_FACE)) return null;
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
