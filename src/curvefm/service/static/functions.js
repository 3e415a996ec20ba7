// Per-vertex functions on a mesh: bounds, the coordinates function, a region around a vertex, and rows read
// through a pointwise map. All are flat typed arrays in internal vertex order (row i = vertex i).

/** Per-axis bounds of packed xyz vertices: { low: [x, y, z], high: [x, y, z] }. */
export function bounds(vertices) {
  const low = [Infinity, Infinity, Infinity];
  const high = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < vertices.length; i += 3) {
    for (let c = 0; c < 3; c++) {
      low[c] = Math.min(low[c], vertices[i + c]);
      high[c] = Math.max(high[c], vertices[i + c]);
    }
  }
  return { low, high };
}

/** The length of the diagonal of the bounding box of packed xyz vertices. */
export function diagonal(vertices) {
  const { low, high } = bounds(vertices);
  return Math.hypot(high[0] - low[0], high[1] - low[1], high[2] - low[2]);
}

/** Source coordinates scaled to [0, 1] per axis (n x 3), as the service's ``xyz`` function. */
export function xyzValues(vertices) {
  const { low, high } = bounds(vertices);
  const out = new Float32Array(vertices.length);
  for (let i = 0; i < vertices.length; i += 3) {
    for (let c = 0; c < 3; c++) out[i + c] = (vertices[i + c] - low[c]) / Math.max(high[c] - low[c], 1e-30);
  }
  return out;
}

/**
 * The region around ``center`` (internal id): vertices within ``radius`` (Euclidean), at most ``maxCount``
 * nearest (the ids travel in a URL). Returns { ids: internal ids, indicator: Float32Array(n), 1 inside }.
 */
export function regionAround(vertices, center, radius, maxCount = 1000) {
  const [cx, cy, cz] = vertices.subarray(3 * center, 3 * center + 3);
  const inside = [];
  for (let i = 0, n = vertices.length / 3; i < n; i++) {
    const d2 = (vertices[3 * i] - cx) ** 2 + (vertices[3 * i + 1] - cy) ** 2 + (vertices[3 * i + 2] - cz) ** 2;
    if (d2 <= radius * radius) inside.push([d2, i]);
  }
  inside.sort((a, b) => a[0] - b[0]);
  const ids = inside.slice(0, maxCount).map(([, i]) => i);
  const indicator = new Float32Array(vertices.length / 3);
  for (const i of ids) indicator[i] = 1;
  return { ids, indicator };
}

/** Rows of ``values`` (d columns) read through a pointwise map: out row j = values row p2p[j]. */
export function pullBack(values, columns, p2p) {
  const out = new Float32Array(p2p.length * columns);
  for (let j = 0; j < p2p.length; j++) {
    for (let c = 0; c < columns; c++) out[j * columns + c] = values[p2p[j] * columns + c];
  }
  return out;
}
