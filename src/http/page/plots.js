// Convergence: the plots of a run's history.

import { $, view } from "./state.js";
import { range } from "./viewer.js";

export function drawConvergence() {
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
