// CesiumJS itself reading a tile pyramid: serves DIR on a loopback port (or reads a server's
// layer at URL, which ends in /), opens it with CesiumTerrainProvider (layer.json, then each
// tile as a client asks for it), and prints one JSON line per tile with what Cesium decoded,
// then the largest height gap Cesium sees across the common side of neighbours at the
// deepest level. Usage: node check.mjs DIR|URL
import http from "node:http";
import fs from "node:fs";
import path from "node:path";
import { CesiumTerrainProvider } from "@cesium/engine";

const dir = process.argv[2];
const remote = dir.startsWith("http://");
const server = http.createServer((req, res) => {
  const file = path.join(dir, decodeURIComponent(new URL(req.url, "http://localhost").pathname));
  fs.readFile(file, (err, data) => {
    res.writeHead(err ? 404 : 200);
    res.end(err ? undefined : data);
  });
});
if (!remote) await new Promise((resolve) => server.listen(0, "127.0.0.1", resolve));
try {
  const base = remote ? dir : `http://127.0.0.1:${server.address().port}/`;
  const provider = await CesiumTerrainProvider.fromUrl(base, { requestVertexNormals: true });
  const scheme = provider.tilingScheme;
  const layer = await (await fetch(`${base}layer.json`)).json();
  const deepest = new Map();
  for (let z = 0; z <= layer.maxzoom; z++) {
    for (const range of layer.available[z]) {
      for (let tms = range.startY; tms <= range.endY; tms++) {
        for (let x = range.startX; x <= range.endX; x++) {
          // Cesium counts rows from the north; the files, as TMS, from the south.
          const y = scheme.getNumberOfYTilesAtLevel(z) - 1 - tms;
          const available = provider.getTileDataAvailable(x, y, z);
          const data = await provider.requestTileGeometry(x, y, z);
          const tile = {
            z, x, y: tms, available,
            vertices: data._quantizedVertices.length / 3,
            triangles: data._indices.length / 3,
            normals: data._encodedNormals ? data._encodedNormals.length / 2 : 0,
            edges: [data._westIndices.length, data._southIndices.length, data._eastIndices.length, data._northIndices.length],
          };
          console.log(JSON.stringify(tile));
          if (z === layer.maxzoom) deepest.set(`${x}/${tms}`, { data, rect: scheme.tileXYToRectangle(x, y, z) });
        }
      }
    }
  }
  // Heights Cesium interpolates along each east side, from the tile and from its neighbour.
  let gap = 0, sides = 0;
  for (const [key, { data, rect }] of deepest) {
    const [x, tms] = key.split("/").map(Number);
    const east = deepest.get(`${x + 1}/${tms}`);
    if (!east) continue;
    sides++;
    for (let k = 0; k <= 100; k++) {
      const lat = rect.south + ((rect.north - rect.south) * k) / 100;
      const a = data.interpolateHeight(rect, rect.east, lat);
      const b = east.data.interpolateHeight(east.rect, east.rect.west, lat);
      gap = Math.max(gap, Math.abs(a - b));
    }
  }
  console.log(JSON.stringify({ sides, gap }));
} finally {
  if (!remote) server.close();
}
