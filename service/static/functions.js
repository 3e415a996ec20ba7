// What the viewports show on the surfaces: textures, and per-vertex functions turned into colours.
// All per-vertex arrays are flat typed arrays in internal vertex order (row i = vertex i).
import * as THREE from "three";

/** A checkerboard whose hue turns with u and whose saturation grows with v, so that a carried texture shows
 * orientation as well as distortion. u wraps smoothly (hue 360 = hue 0), matching cylindrical texcoords. */
export function checkerboardTexture(tiles = 12, size = 512) {
  const canvas = document.createElement("canvas");
  canvas.width = canvas.height = size;
  const context = canvas.getContext("2d");
  const step = size / tiles;
  for (let i = 0; i < tiles; i++) {
    for (let j = 0; j < tiles; j++) {
      const lightness = (i + j) % 2 === 0 ? 80 : 52;
      const saturation = 25 + (50 * j) / (tiles - 1);
      context.fillStyle = `hsl(${(360 * i) / tiles} ${saturation}% ${lightness}%)`;
      context.fillRect(i * step, (tiles - 1 - j) * step, step, step); // canvas rows run down, v runs up
    }
  }
  return finishTexture(new THREE.CanvasTexture(canvas));
}

/** A texture from an image file the user picked (the source's own texture image). */
export async function imageTexture(file) {
  const url = URL.createObjectURL(file);
  try {
    return finishTexture(await new THREE.TextureLoader().loadAsync(url));
  } catch {
    throw new Error(`'${file.name}' is not an image the browser can read`);
  } finally {
    URL.revokeObjectURL(url);
  }
}

function finishTexture(texture) {
  texture.colorSpace = THREE.SRGBColorSpace;
  texture.wrapS = texture.wrapT = THREE.RepeatWrapping; // carried coordinates may leave [0, 1]
  return texture;
}

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

// sRGB byte -> linear (vertex colours are linear in three.js's colour management)
const SRGB_TO_LINEAR = Float32Array.from(
  { length: 256 },
  (_, i) => new THREE.Color().setRGB(i / 255, 0, 0, THREE.SRGBColorSpace).r,
);
const byte = (x) => (x >= 1 ? 255 : x <= 0 ? 0 : Math.round(x * 255));

/** Colours (n x 3, into ``out``) from n x 3 values in [0, 1] (clamped): coordinates as colour. */
export function rgbColors(values, out) {
  for (let i = 0; i < out.length; i++) out[i] = SRGB_TO_LINEAR[byte(values[i])];
  return out;
}

// grey -> amber -> red: how much of the selected region a vertex receives
const RAMP = [
  [0.86, 0.87, 0.89],
  [0.98, 0.72, 0.22],
  [0.78, 0.12, 0.1],
];
const RAMP_LUT = Float32Array.from({ length: 256 * 3 }, (_, index) => {
  const t = Math.floor(index / 3) / 255;
  const c = index % 3;
  const [a, b, s] = t < 0.5 ? [RAMP[0], RAMP[1], t * 2] : [RAMP[1], RAMP[2], t * 2 - 1];
  return SRGB_TO_LINEAR[byte(a[c] + (b[c] - a[c]) * s)];
});

/** Colours (n x 3, into ``out``) of a scalar in [0, 1] (clamped) on the grey-amber-red ramp. */
export function rampColors(values, out) {
  for (let i = 0; i < values.length; i++) {
    const k = 3 * byte(values[i]);
    out[3 * i] = RAMP_LUT[k];
    out[3 * i + 1] = RAMP_LUT[k + 1];
    out[3 * i + 2] = RAMP_LUT[k + 2];
  }
  return out;
}
