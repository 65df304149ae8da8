// Colours: the map the server's pictures use, and how numbers are shown beside them.

// Viridis at 9 stops, interpolated: the same map as the server's SVG and PNG pictures (a test
// of the server checks the stops).
const VIRIDIS = [
  [68, 1, 84], [71, 44, 122], [58, 81, 139], [44, 113, 142], [32, 144, 140],
  [39, 173, 128], [92, 200, 98], [170, 219, 49], [253, 231, 37],
];
export function viridis(t) {
  const s = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 0)) * (VIRIDIS.length - 1);
  const i = Math.min(VIRIDIS.length - 2, Math.floor(s));
  const f = s - i;
  return VIRIDIS[i].map((c, k) => Math.round(c + f * (VIRIDIS[i + 1][k] - c)));
}
export const rgb = (c) => `rgb(${c[0]},${c[1]},${c[2]})`;
export const fmt = (v) => (typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toPrecision(4)) : String(v));
