// Boundary value problems: the example, the problem's JSON, its regions and B as arrows.

import { $, view } from "./state.js";
import { fmt } from "./colours.js";

export const MAGNET = {
  domain: { x: [0, 0.2], y: [0, 0.1] },
  physics: "magnetostatic",
  regions: [
    { x: [0.04, 0.07], y: [0.035, 0.065], current_density: 2e6 },
    { x: [0.11, 0.16], y: [0.02, 0.08], mu_r: 1000 },
  ],
  max_vertices: 20000,
};

export function problemJson() {
  try {
    return JSON.parse($("problem").value);
  } catch (e) {
    return null;
  }
}

export function drawRegions(g, f) {
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
    const current = r.current_density || r.current || r.circuit;
    g.fillStyle = current ? "rgba(214, 96, 77, 0.35)" : r.mu_r || r.bh || r.magnetization || r.material ? "rgba(90, 110, 140, 0.35)" : "rgba(47, 95, 208, 0.25)";
    g.beginPath();
    corners.forEach(([x, y], i) => (i ? g.lineTo(f.x(x), f.y(y)) : g.moveTo(f.x(x), f.y(y))));
    g.closePath();
    g.fill();
    g.strokeStyle = "#394150";
    g.stroke();
    g.fillStyle = "#1d2330";
    g.font = "13px system-ui, sans-serif";
    const law = r.circuit ? `${r.direction === -1 ? "−" : "+"}${fmt(r.turns || 1)} turns of ${r.circuit}`
      : r.current_density ? `J ${fmt(r.current_density)}` : r.current ? `I ${fmt(r.current)} A`
      : r.material ? r.material
      : r.magnetization ? `M ${r.magnetization.map(fmt).join(", ")}` : r.bh ? "B–H" : r.mu_r ? `μr ${fmt(r.mu_r)}` : `k ${fmt(r.k)} f ${fmt(r.f)}`;
    const label = r.name ? `${r.name}: ${law}` : law;
    const left = Math.min(...corners.map(([x]) => f.x(x)));
    const top = Math.min(...corners.map(([, y]) => f.y(y)));
    g.fillText(label, left + 4, top + 15);
  }
}

// B on a coarse grid of the picture: the arrow of the first triangle whose centroid falls in
// each cell, its length by |B| relative to the largest.
export function drawArrows(g, f) {
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
