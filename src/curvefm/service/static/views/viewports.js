// The two viewports, source and target (handles on the page's canvases, like DOM lookups), and what they show
// of the store: the shapes, the carried function painted on the surfaces, the framing of the cameras.
import { state } from "../store.js";
import { rampColors, rgbColors, tintColors } from "./colors.js";
import { $ } from "./dom.js";
import { FrameLoop } from "./frames.js";
import { bounds } from "../functions.js";
import { chooseAxes, curvesMostlyBehind } from "../axes.js";
import { Viewport } from "./viewer.js";

export const SIDES = ["source", "target"];

export const viewports = (() => {
  const frames = new FrameLoop(); // one frame draws both
  return { source: new Viewport($("source-view"), frames), target: new Viewport($("target-view"), frames) };
})();

/** The meshes of the open session, with their names in the captions (and how much of a big shape is drawn). */
export function showShapes() {
  for (const side of SIDES) {
    const { info, mesh } = state.shapes[side];
    viewports[side].setMesh(mesh);
    const drawn = mesh.displayCopy ? ` (display copy: ${mesh.nVertices})` : "";
    $(`${side}-view`).querySelector(".shape-name").textContent = `${info.name} · ${info.n_vertices} vertices${drawn}`;
  }
}

/** The source's values of a carried function (rows per source vertex). */
export function sourceValues(fn) {
  const source = state.shapes.source;
  if (fn === "uv") return source.uv;
  if (fn === "xyz") return source.xyz;
  return state.region?.indicator ?? new Float32Array(source.mesh.nVertices);
}

/** A round-trip drift of this many sqrt(area) or more is shown fully violet: fixed, so the overlay fades as the map
 * improves (FAUST 000 -> 011 with one curve: mean 0.08, worst 0.3; with ten: mean 0.04, worst 0.13). */
export const FULL_DRIFT = 0.1;

const painted = {}; // side -> { fn, rows }: what paint() showed last, for repaint()

/** Paint one side again as it was last painted (the quality overlay changed). */
export function repaint(side) {
  if (painted[side]) paint(side, painted[side].fn, painted[side].rows);
}

/** Paint function ``fn`` on one side: rows per vertex of that side (uv as the texture, xyz and indicator as
 * colours), on the target tinted by the maps' round-trip drift while the quality overlay is on. */
export function paint(side, fn, rows) {
  painted[side] = { fn, rows };
  const view = viewports[side];
  const tint = side === "target" ? qualityTint() : null;
  if (fn === "uv") {
    view.showTexture(state.texture, rows, tint);
    return;
  }
  const fill = fn === "xyz" ? rgbColors : rampColors;
  view.showColors((out) => (tint ? tint(fill(rows, out)) : fill(rows, out)));
}

function qualityTint() {
  const { quality, showQuality } = state;
  const fits = quality?.drift.length === state.shapes.target.mesh.nVertices;
  if (!showQuality || !fits || state.map !== "functional") return null;
  return (out) => tintColors(quality.drift, out, FULL_DRIFT);
}

/** Ring the weakest region of the maps on both shapes (where a new curve helps most) while the overlay is on. */
export function showWeakestRegions() {
  const { quality, showQuality } = state;
  for (const side of SIDES) {
    const worst = quality?.[side === "target" ? "worstTarget" : "worstSource"];
    const vertex = showQuality && worst !== undefined ? state.shapes[side].points.rows([worst])[0] : -1;
    viewports[side].setHighlight(vertex);
  }
}

export function showSource() {
  paint("source", state.fn, sourceValues(state.fn));
}

/** Whether the source's curves (those placed: see placeCurves) mostly lie behind the middle along the axis that
 * faces the viewer (see curvesMostlyBehind). */
function curvesBehind(vertices, towards) {
  const axis = ["x", "y", "z"].indexOf(towards);
  const { low, high } = bounds(vertices);
  const { points } = state.shapes.source;
  const placed = (state.session?.curves ?? []).filter((curve) => points.has(curve.path_source));
  return curvesMostlyBehind(placed.map((curve) => points.path(curve.path_source)), towards, (low[axis] + high[axis]) / 2);
}

/** Turn both shapes as the Up control says, the side where the source's curves lie more towards the viewer, and
 * frame them with one camera distance, so that linked cameras frame both. */
export function orientViews() {
  const { vertices, faces } = state.shapes.source.mesh;
  const axes = chooseAxes(vertices, faces, $("up-select").value);
  axes.flip = curvesBehind(vertices, axes.towards);
  const [source, target] = SIDES.map((side) => viewports[side].orient(axes));
  const both = source.max(target);
  for (const side of SIDES) viewports[side].resetCamera(both);
}
