// The picture: the plane (canvas) and the surface (WebGL), drawn from `view`.

import { $, view } from "./state.js";
import { fmt, rgb, viridis } from "./colours.js";
import { drawArrows, drawRegions, problemJson } from "./solutions.js";

let drawPending = false;
export function scheduleDraw() {
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
export function frame(canvas, d) {
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

export function range(values) {
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
    if (view.kind === "solution") drawRegions(g, f, problemJson(), true);
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
  // The regions of the request that made the solution (not of a job opened by its address).
  if (view.kind === "solution" && view.request && view.request.regions) drawRegions(g, f, view.request, false);
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


export const turn = { yaw: -0.6, pitch: 0.9 };
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
