// What the viewports paint on the surfaces: textures, and per-vertex functions turned into colours.
// Per-vertex arrays are flat typed arrays in internal vertex order (row i = vertex i).
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
const RAMP_LUT = lookupTable(RAMP);

/** 256 linear RGB triples along a three-colour sRGB ramp. */
function lookupTable(ramp) {
  return Float32Array.from({ length: 256 * 3 }, (_, index) => {
    const t = Math.floor(index / 3) / 255;
    const c = index % 3;
    const [a, b, s] = t < 0.5 ? [ramp[0], ramp[1], t * 2] : [ramp[1], ramp[2], t * 2 - 1];
    return SRGB_TO_LINEAR[byte(a[c] + (b[c] - a[c]) * s)];
  });
}

// white -> light blue -> violet: how far a vertex drifts on the maps' round trip (multiplies the surface's colours;
// away from the region tool's grey-amber-red, and the overlay's legend in index.html draws the same stops)
const TINT = [
  [1, 1, 1],
  [0.62, 0.78, 1],
  [0.35, 0.1, 0.65],
];
const TINT_LUT = lookupTable(TINT);

/** Multiply colours (n x 3, ``out``) by the tint of each vertex's drift (units of sqrt(area)); a drift of
 * ``full`` or more is fully violet. */
export function tintColors(drift, out, full) {
  for (let i = 0; i < drift.length; i++) {
    const k = 3 * byte(drift[i] / full);
    out[3 * i] *= TINT_LUT[k];
    out[3 * i + 1] *= TINT_LUT[k + 1];
    out[3 * i + 2] *= TINT_LUT[k + 2];
  }
  return out;
}

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
