// The forms: which one is shown, the request it describes, the address that shares it, the
// API key, and errors shown next to their fields.

import { $, view } from "./state.js";

// Shows tab `which` ("mesh", "solve", "device" or "terrain") and its form: a device is a
// problem, edited in the problem's form with the device's tables shown.
export function showTab(which) {
  view.kind = which === "solve" || which === "device" ? "solution" : "mesh";
  const form = which === "device" ? "solve" : which;
  for (const tab of ["mesh", "solve", "device", "terrain"]) $(`tab-${tab}`).setAttribute("aria-selected", String(which === tab));
  for (const name of ["mesh", "solve", "terrain"]) $(`${name}-form`).hidden = form !== name;
  $("device-editor").hidden = which !== "device";
}

// The mesh request the form describes; `bad` collects field errors found before sending.
export function meshRequest(bad) {
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
  if (view.kind === "solution") q.set("colour", $("solve-colour").value);
  // Spaces as %20, not `+`: the page reads a `+` in an address as the plus a person typing
  // ?function=x+y means (readAddress), so a `+` written here must stand for itself alone.
  return `${location.pathname}?${q.toString().replace(/\+/g, "%20")}`;
}

const shellQuote = (s) => `'${s.replace(/'/g, `'\\''`)}'`;
export function curlLine(req) {
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
export function updateAddress() {
  if (!view.request) return;
  const share = shareAddress(view.request);
  $("share").href = share;
  history.replaceState(null, "", share);
}

// A server with keys needs one on every /v1 request; the page keeps it in this browser.
export const KEY = "meshfit-api-key";
export function authHeaders() {
  const key = localStorage.getItem(KEY);
  return key ? { authorization: `Bearer ${key}` } : {};
}


export function clearErrors() {
  for (const p of document.querySelectorAll(".field-error")) p.textContent = "";
  for (const el of document.querySelectorAll(".invalid")) el.classList.remove("invalid");
}

export function showError(field, text) {
  const p = document.querySelector(`.field-error[data-for="${field}"]`) || $("general-error");
  p.textContent = text;
  const input = { function: $("function"), grid: $("grid-file"), problem: $("problem"),
    max_vertices: $("max_vertices"), tolerance: $("tolerance"), domain: $("x0"), dem: $("dem-file") }[field];
  if (input) input.classList.add("invalid");
  return input;
}

// A problem document (RFC 9457), shown where it says the problem is.
export function showProblem(problem) {
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
