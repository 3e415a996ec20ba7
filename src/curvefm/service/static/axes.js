// How a shape is turned to be shown: which of its axes points up, which at the viewer, and from which side, from
// its vertices, faces and curves alone (no three.js: Node runs this module in the tests).
import { bounds } from "./functions.js";

const NAMES = ["x", "y", "z"];
const FOOT_SLAB = 0.1; // a shape's feet: the parts of its lowest tenth along the up axis
const FOOT_SHARE = 0.02; // a part with fewer of that tenth's vertices is a stray bump, not a foot

/** The view of a shape (packed xyz ``vertices``, triangle ``faces``): which of its axes points up and which towards
 * the viewer. ``up = "auto"``: z, as in TOSCA and most scanned data, unless the shape is thinnest along z (then y,
 * the graphics convention of FAUST and SMPL-like bodies), or unless z would stand it on one point while y stands it
 * on feet: its lowest tenth along z is one piece (a tail, a nose) and along y several (paws). That is a y-up animal
 * lying along z, as the cat and the lion of pyFM's non-isometric pair, which z-up stood on their tails. The viewer
 * looks along the thinnest remaining axis, so the shape shows its broad side. */
export function chooseAxes(vertices, faces, up) {
  const { low, high } = bounds(vertices);
  const extent = [0, 1, 2].map((c) => high[c] - low[c]);
  const byExtent = [0, 1, 2].sort((a, b) => extent[a] - extent[b]).map((c) => NAMES[c]);
  const upAxis = up === "auto" ? automaticUp(vertices, faces, byExtent[0], low, extent) : up;
  const towards = byExtent.find((name) => name !== upAxis);
  return { up: upAxis, towards };
}

function automaticUp(vertices, faces, thinnest, low, extent) {
  if (thinnest === "z") return "y";
  const feet = (axis) => footCount(vertices, faces, axis, low[axis] + FOOT_SLAB * extent[axis]);
  return feet(2) === 1 && feet(1) > 1 ? "y" : "z";
}

/** How many separate parts (joined by the faces' edges, each with FOOT_SHARE of the vertices or more) the vertices
 * below ``below`` along ``axis`` make. */
export function footCount(vertices, faces, axis, below) {
  const n = vertices.length / 3;
  const low = (v) => vertices[3 * v + axis] <= below;
  const parent = Int32Array.from({ length: n }, (_, v) => v);
  const root = (v) => {
    while (parent[v] !== v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (let f = 0; f < faces.length; f += 3) {
    for (const [a, b] of [[faces[f], faces[f + 1]], [faces[f + 1], faces[f + 2]], [faces[f + 2], faces[f]]]) {
      if (low(a) && low(b)) parent[root(a)] = root(b);
    }
  }
  const sizes = new Map();
  let total = 0;
  for (let v = 0; v < n; v++) {
    if (!low(v)) continue;
    total += 1;
    sizes.set(root(v), (sizes.get(root(v)) ?? 0) + 1);
  }
  return [...sizes.values()].filter((size) => size >= FOOT_SHARE * total).length;
}

/** Whether the view should show the shape from behind (the ``towards`` axis negated): only when over two thirds of the
 * curves, and two at least, lie behind the middle along it. Each curve (packed xyz points) counts once, however long: one long
 * curve on FAUST's back turned the view from the front curves. */
export function curvesMostlyBehind(paths, axis, middle) {
  const index = NAMES.indexOf(axis);
  let behind = 0;
  for (const path of paths) {
    let depth = 0;
    for (let i = index; i < path.length; i += 3) depth += path[i] - middle;
    if (depth < 0) behind += 1;
  }
  return behind >= 2 && behind > (2 * paths.length) / 3;
}
