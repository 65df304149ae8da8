// Magnetic devices: the device tab's tables of regions and circuits, and the B–H plot of the
// material in focus. The problem's JSON stays the one truth: every control writes into it,
// and the tables are drawn again from it.

import { $ } from "./state.js";
import { authHeaders } from "./form.js";
import { fmt } from "./colours.js";
import { problemJson } from "./solutions.js";

// The README's electromagnet, lighter: a C-core of library steel, an armature across its
// gap, and a coil of two sides on one circuit, in mm, 50 mm deep.
export const DEVICE = {
  physics: "magnetostatic",
  unit: "mm",
  depth: 50,
  domain: { x: [-100, 100], y: [-100, 100] },
  circuits: { coil: { current: 10 } },
  regions: [
    { name: "core", material: "M400-50A",
      polygon: [[-30, -30], [30, -30], [30, -10], [-10, -10], [-10, 10], [30, 10], [30, 30], [-30, 30]] },
    { name: "armature", material: "M400-50A", x: [32, 42], y: [-30, 30] },
    { name: "coil+", material: "copper", circuit: "coil", turns: 100, direction: 1, x: [-8, 0], y: [-8, 8] },
    { name: "coil-", material: "copper", circuit: "coil", turns: 100, direction: -1, x: [-40, -32], y: [-8, 8] },
  ],
  max_vertices: 10000,
};

const MU_0 = 1.25663706212e-6;
const OWN = "(its own law)";
let library = []; // GET /v1/materials
let focus = 0; // the region whose material the plot shows

// The built-in materials, once; the tables are drawn again when they arrive.
export async function loadLibrary(then) {
  if (library.length) return;
  try {
    const response = await fetch("/v1/materials", { headers: authHeaders() });
    if (response.ok) library = (await response.json()).materials;
  } catch (e) {
    // Without the list a material is still typed into the JSON by name.
  }
  then();
}

// Rewrites the problem with `change` applied and draws everything again.
function edit(change, redraw) {
  const p = problemJson();
  if (!p) return;
  change(p);
  $("problem").value = JSON.stringify(p, null, 2);
  renderDevice(redraw);
  redraw();
}

function element(tag, props = {}, children = []) {
  const el = Object.assign(document.createElement(tag), props);
  for (const c of children) el.append(c);
  return el;
}

function select(options, value, onChange) {
  const s = element("select");
  for (const o of options) {
    if (Array.isArray(o)) {
      const [label, items] = o;
      s.append(element("optgroup", { label }, items.map((v) => element("option", { value: v, textContent: v }))));
    } else {
      s.append(element("option", { value: o, textContent: o }));
    }
  }
  s.value = value;
  s.addEventListener("change", () => onChange(s.value));
  return s;
}

function numberInput(value, onChange, label) {
  const input = element("input", { value: value ?? "", inputMode: "decimal" });
  input.setAttribute("aria-label", label);
  input.addEventListener("change", () => {
    const v = Number(input.value);
    if (input.value.trim() !== "" && Number.isFinite(v)) onChange(v);
  });
  return input;
}

// The tables of the problem in the editor; hidden unless it is magnetostatic.
export function renderDevice(redraw = () => {}) {
  const p = problemJson();
  const device = p && p.physics === "magnetostatic" && Array.isArray(p.regions);
  $("device").hidden = !device;
  $("device-none").hidden = device;
  if (!device) return;
  const own = Object.keys(p.materials || {});
  const kinds = [...new Set(library.map((m) => m.kind))];
  const materialOptions = [
    ...(own.length ? [["this request", own]] : []),
    ...kinds.map((k) => [k, library.filter((m) => m.kind === k).map((m) => m.name)]),
  ];
  const circuits = Object.keys(p.circuits || {});
  const rows = p.regions.map((r, i) => {
    const material = r.material || (r.mu_r || r.bh || r.magnetization ? OWN : "air");
    const options = material === OWN || !materialOptions.flat(2).includes(material)
      ? [material, ...materialOptions] : materialOptions;
    const cells = [
      element("input", { value: r.name || "", onchange: (e) => edit((q) => (q.regions[i].name = e.target.value || undefined), redraw) }),
      select(options, material, (v) => edit((q) => {
        const region = q.regions[i];
        for (const key of ["mu_r", "bh", "magnetization"]) delete region[key];
        region.material = v;
        focus = i;
      }, redraw)),
      select(["—", ...circuits], r.circuit || "—", (v) => edit((q) => {
        const region = q.regions[i];
        if (v === "—") for (const key of ["circuit", "turns", "direction"]) delete region[key];
        else Object.assign(region, { circuit: v, turns: region.turns || 1, direction: region.direction || 1 });
      }, redraw)),
      r.circuit ? numberInput(r.turns ?? 1, (v) => edit((q) => (q.regions[i].turns = v), redraw), "turns") : "",
      r.circuit ? select(["+1", "−1"], r.direction === -1 ? "−1" : "+1",
        (v) => edit((q) => (q.regions[i].direction = v === "−1" ? -1 : 1), redraw)) : "",
    ];
    const row = element("tr", { className: i === focus ? "focus" : "" }, cells.map((c) => element("td", {}, [c])));
    row.dataset.region = String(i);
    row.addEventListener("focusin", () => {
      if (focus === i) return;
      focus = i;
      for (const tr of $("device-regions").querySelectorAll("tr")) tr.className = tr === row ? "focus" : "";
      drawBh(problemJson());
    });
    return row;
  });
  $("device-regions").replaceChildren(...rows);
  const circuitRows = circuits.map((name) => element("tr", {}, [
    element("td", { textContent: name }),
    element("td", {}, [numberInput(p.circuits[name].current, (v) => edit((q) => (q.circuits[name].current = v), redraw), `current of ${name}`)]),
    element("td", {}, [element("button", {
      type: "button",
      textContent: "remove",
      title: `remove ${name} and make its coils plain regions`,
      onclick: () => edit((q) => removeCircuit(q, name), redraw),
    })]),
  ]));
  $("device-circuits").replaceChildren(...circuitRows);
  drawBh(p);
}

// Removes circuit `name` from `q`; its coil sides keep their material and lose their turns.
function removeCircuit(q, name) {
  delete q.circuits[name];
  for (const r of q.regions) {
    if (r.circuit === name) for (const key of ["circuit", "turns", "direction"]) delete r[key];
  }
}

// Adds a circuit named c1, c2, … carrying 1 A: a region's circuit column then offers it (a
// circuit no region is a coil of is refused by the server, naming it).
export function addCircuit(redraw) {
  edit((q) => {
    q.circuits = q.circuits || {};
    let k = 1;
    while (q.circuits[`c${k}`]) k++;
    q.circuits[`c${k}`] = { current: 1 };
  }, redraw);
}

// The law of region `r`: a B–H table, or μr (with a magnet's Br).
function lawOf(p, r) {
  if (!r) return null;
  if (r.material) {
    const named = (p.materials || {})[r.material] || library.find((m) => m.name.toLowerCase() === r.material.toLowerCase());
    return named ? { name: r.material, ...named } : null;
  }
  return { name: "its own law", bh: r.bh, mu_r: r.mu_r ?? 1, br: r.magnetization ? MU_0 * Math.hypot(...r.magnetization) : undefined };
}

// The focused region's B–H curve: the table's points joined (the solver's monotone cubic
// passes through them), or a straight line for a linear law or a magnet's recoil line.
function drawBh(p) {
  const canvas = $("bh-plot");
  const g = canvas.getContext("2d");
  g.fillStyle = "#ffffff";
  g.fillRect(0, 0, canvas.width, canvas.height);
  const law = lawOf(p, p && p.regions && p.regions[focus]);
  const title = $("bh-title");
  if (!law) {
    title.textContent = "no material";
    return;
  }
  let points;
  let what;
  if (Array.isArray(law.bh) && law.bh.length > 1) {
    points = law.bh;
    what = `${law.name}: B–H table, ${points.length} points`;
  } else if (law.br !== undefined || law.hc !== undefined) {
    const mu = law.mu_r ?? (law.br / (MU_0 * law.hc));
    const br = law.br ?? MU_0 * mu * law.hc;
    const hc = law.hc ?? br / (MU_0 * mu);
    points = [[-hc, 0], [0, br]];
    what = `${law.name}: magnet, Br ${fmt(br)} T, Hc ${fmt(hc)} A/m`;
  } else {
    const mu = law.mu_r ?? 1;
    points = [[0, 0], [1.5 / (MU_0 * mu), 1.5]];
    what = `${law.name}: μr ${fmt(mu)}`;
  }
  title.textContent = what;
  canvas.dataset.points = String(points.length);
  // A steel's table spans decades of H: its knee shows on a logarithmic axis.
  const positive = points.filter(([h]) => h > 0);
  const log = Array.isArray(law.bh) && positive.length > 1 && positive.at(-1)[0] / positive[0][0] > 100;
  if (log) points = positive;
  const hs = points.map(([h]) => (log ? Math.log10(h) : h));
  const bs = points.map(([, b]) => b);
  const [h0, h1] = [log ? Math.min(...hs) : Math.min(0, ...hs), Math.max(...hs)];
  const [b0, b1] = [Math.min(0, ...bs), Math.max(...bs)];
  const pad = { l: 40, r: 10, t: 10, b: 28 };
  const X = (h) => pad.l + (((log ? Math.log10(h) : h) - h0) / (h1 - h0 || 1)) * (canvas.width - pad.l - pad.r);
  const Y = (b) => canvas.height - pad.b - ((b - b0) / (b1 - b0 || 1)) * (canvas.height - pad.t - pad.b);
  g.strokeStyle = "#9aa1ad";
  g.lineWidth = 1;
  g.strokeRect(pad.l, pad.t, canvas.width - pad.l - pad.r, canvas.height - pad.t - pad.b);
  g.fillStyle = "#5b6474";
  g.font = "11px system-ui, sans-serif";
  g.fillText(`${fmt(b1)} T`, 2, pad.t + 8);
  g.fillText(`${fmt(b0)}`, 2, canvas.height - pad.b);
  const axis = log ? `H ${fmt(10 ** h0)} … ${fmt(10 ** h1)} A/m, logarithmic` : `H ${fmt(h0)} … ${fmt(h1)} A/m`;
  g.fillText(axis, pad.l, canvas.height - 8);
  g.strokeStyle = "#2f5fd0";
  g.lineWidth = 2;
  g.beginPath();
  points.forEach(([h, b], k) => (k ? g.lineTo(X(h), Y(b)) : g.moveTo(X(h), Y(b))));
  g.stroke();
  g.fillStyle = "#2f5fd0";
  for (const [h, b] of points) g.fillRect(X(h) - 1.5, Y(b) - 1.5, 3, 3);
}
