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

// The server's ARC_SEGMENT_ANGLE and MAX_POLYGON_POINTS (src/spec/solution.rs, src/solve/polygon.rs).
const ARC_SEGMENT_ANGLE = 5;
const MAX_POLYGON_POINTS = 1000;

// A region's outline: a rectangle's corners, or a polygon's with each arc drawn as the
// server draws it (equal segments of at most max_segment_angle degrees). An arc the server
// would refuse is drawn as its chord.
export function outline(r) {
  if (Array.isArray(r.x) && Array.isArray(r.y)) return [[r.x[0], r.y[0]], [r.x[1], r.y[0]], [r.x[1], r.y[1]], [r.x[0], r.y[1]]];
  if (!Array.isArray(r.polygon)) return null;
  const entries = r.polygon;
  const n = entries.length;
  const corners = [];
  entries.forEach((entry, k) => {
    if (Array.isArray(entry)) return corners.push(entry);
    const [from, to] = [entries[(k + n - 1) % n], entries[(k + 1) % n]];
    if (!entry || !Array.isArray(from) || !Array.isArray(to) || !(Math.abs(entry.arc) < 360) || !entry.arc) return;
    if (from[0] === to[0] && from[1] === to[1]) return;
    const sweep = (entry.arc * Math.PI) / 180;
    const segments = Math.ceil(Math.abs(entry.arc) / (entry.max_segment_angle || ARC_SEGMENT_ANGLE));
    const [dx, dy] = [to[0] - from[0], to[1] - from[1]];
    const chord = Math.hypot(dx, dy);
    const radius = (0.5 * chord) / Math.sin(Math.abs(sweep) / 2);
    const off = (radius * Math.cos(Math.abs(sweep) / 2) * Math.sign(sweep)) / chord;
    const [cx, cy] = [(from[0] + to[0]) / 2 - off * dy, (from[1] + to[1]) / 2 + off * dx];
    const start = Math.atan2(from[1] - cy, from[0] - cx);
    for (let i = 1; i < segments && segments <= MAX_POLYGON_POINTS; i++) {
      const phi = start + (sweep * i) / segments;
      corners.push([cx + radius * Math.cos(phi), cy + radius * Math.sin(phi)]);
    }
  });
  return corners;
}

// The regions of `p`, outlined and named; filled by kind before a solution covers them.
export function drawRegions(g, f, p, filled) {
  if (!p || !Array.isArray(p.regions)) return;
  for (const r of p.regions) {
    const corners = outline(r);
    if (!corners || corners.length < 3) continue;
    g.beginPath();
    corners.forEach(([x, y], i) => (i ? g.lineTo(f.x(x), f.y(y)) : g.moveTo(f.x(x), f.y(y))));
    g.closePath();
    if (filled) {
      const current = r.current_density || r.current || r.circuit;
      g.fillStyle = current ? "rgba(214, 96, 77, 0.35)" : r.mu_r || r.bh || r.magnetization || r.material ? "rgba(90, 110, 140, 0.35)" : "rgba(47, 95, 208, 0.25)";
      g.fill();
    }
    g.strokeStyle = filled ? "#394150" : "rgba(255, 255, 255, 0.85)";
    g.lineWidth = 1.2;
    g.stroke();
    g.font = "13px system-ui, sans-serif";
    const law = r.circuit ? `${r.direction === -1 ? "−" : "+"}${fmt(r.turns || 1)} turns of ${r.circuit}`
      : r.current_density ? `J ${fmt(r.current_density)}` : r.current ? `I ${fmt(r.current)} A`
      : r.material ? r.material
      : r.magnetization ? `M ${r.magnetization.map(fmt).join(", ")}` : r.bh ? "B–H" : r.mu_r ? `μr ${fmt(r.mu_r)}` : `k ${fmt(r.k)} f ${fmt(r.f)}`;
    const label = r.name ? `${r.name}: ${law}` : law;
    const left = Math.min(...corners.map(([x]) => f.x(x)));
    const top = Math.min(...corners.map(([, y]) => f.y(y)));
    if (!filled) {
      // White text on a dark halo reads over any colour of the field.
      g.lineWidth = 3;
      g.strokeStyle = "rgba(20, 24, 32, 0.8)";
      g.strokeText(label, left + 4, top + 15);
    }
    g.fillStyle = filled ? "#1d2330" : "#ffffff";
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
