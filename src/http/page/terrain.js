// Terrain tiles: a DEM uploaded as a dataset (POST /v1/datasets), then what a map needs to
// show it: the layer.json address, the CesiumJS lines to paste and the same with curl.

import { $ } from "./state.js";
import { authHeaders, showError } from "./form.js";

// Uploads `file` and shows the dataset, or the problem the server found with it.
export async function uploadDem(file) {
  const body = new FormData();
  body.append("grid", file, file.name);
  $("dem-upload").disabled = true;
  document.body.dataset.state = "running";
  try {
    const response = await fetch("/v1/datasets", { method: "POST", body, headers: authHeaders() });
    const doc = await response.json();
    if (!response.ok) {
      document.body.dataset.state = "failed";
      $("terrain-result").hidden = true;
      return showError("dem", doc.detail || `the server answered ${response.status}`);
    }
    showDataset(doc, file.name);
    document.body.dataset.state = "done";
  } catch (e) {
    document.body.dataset.state = "failed";
    showError("dem", `the upload failed: ${e.message}`);
  } finally {
    $("dem-upload").disabled = false;
  }
}

function showDataset(d, name) {
  const rows = [
    ["id", d.id],
    ["samples", `${d.size[0]} × ${d.size[1]}`],
    ["bounds (W, S, E, N)", d.bounds.map((v) => v.toFixed(5)).join(", ")],
    ["heights, m", `${d.heights[0]} to ${d.heights[1]}`],
    ["levels", `0 to ${d.max_zoom}`],
  ];
  const body = $("dataset").tBodies[0];
  body.replaceChildren(
    ...rows.map(([k, v]) => {
      const tr = document.createElement("tr");
      tr.dataset.stat = k;
      for (const text of [k, v]) tr.appendChild(document.createElement("td")).textContent = text;
      return tr;
    }),
  );
  const layer = new URL(d.links.layer, location.href).href;
  $("layer-url").href = layer;
  $("layer-url").textContent = layer;
  const [w, s, e, n] = d.bounds;
  $("cesium-snippet").textContent = [
    "const viewer = new Cesium.Viewer(\"cesiumContainer\", {",
    `  terrainProvider: await Cesium.CesiumTerrainProvider.fromUrl("${layer}", {`,
    "    requestVertexNormals: true,",
    "  }),",
    "});",
    `viewer.camera.flyTo({ destination: Cesium.Rectangle.fromDegrees(${w}, ${s}, ${e}, ${n}) });`,
    "// A page of another origin needs the server started with MESHFIT_CORS_ORIGINS naming it.",
  ].join("\n");
  const origin = location.origin;
  $("terrain-curl").textContent = [
    `curl -s ${origin}/v1/datasets -F grid=@'${name.replace(/'/g, "'\\''")}'`,
    `curl -s ${layer}`,
    `curl -s --compressed ${origin}/v1/tiles/${d.id}/0/0/0.terrain -o 0-0-0.terrain`,
  ].join("\n");
  $("terrain-result").hidden = false;
}
