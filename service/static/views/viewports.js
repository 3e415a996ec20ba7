// The two viewports, source and target (handles on the page's canvases, like DOM lookups), and what they show
// of the store: the shapes, the carried function painted on the surfaces, the framing of the cameras.
import { state } from "../store.js";
import { rampColors, rgbColors } from "./colors.js";
import { $ } from "./dom.js";
import { FrameLoop } from "./frames.js";
import { chooseAxes, Viewport } from "./viewer.js";

export const SIDES = ["source", "target"];

export const viewports = (() => {
  const frames = new FrameLoop(); // one frame draws both
  return { source: new Viewport($("source-view"), frames), target: new Viewport($("target-view"), frames) };
})();

/** The meshes of the open session, with their names in the captions. */
export function showShapes() {
  for (const side of SIDES) {
    const { info, mesh } = state.shapes[side];
    viewports[side].setMesh(mesh);
    $(`${side}-view`).querySelector(".shape-name").textContent = `${info.name} · ${info.n_vertices} vertices`;
  }
}

/** The source's values of a carried function (rows per source vertex). */
export function sourceValues(fn) {
  const source = state.shapes.source;
  if (fn === "uv") return source.uv;
  if (fn === "xyz") return source.xyz;
  return state.region?.indicator ?? new Float32Array(source.mesh.nVertices);
}

/** Paint function ``fn`` on one side: rows per vertex of that side (uv as the texture, xyz and indicator as
 * colours). */
export function paint(side, fn, rows) {
  const view = viewports[side];
  if (fn === "uv") view.showTexture(state.texture, rows);
  else if (fn === "xyz") view.showColors((out) => rgbColors(rows, out));
  else view.showColors((out) => rampColors(rows, out));
}

export function showSource() {
  paint("source", state.fn, sourceValues(state.fn));
}

/** Turn both shapes as the Up control says and frame them with one camera distance, so that linked cameras
 * frame both. */
export function orientViews() {
  const axes = chooseAxes(state.shapes.source.mesh.vertices, $("up-select").value);
  const [source, target] = SIDES.map((side) => viewports[side].orient(axes));
  const both = source.max(target);
  for (const side of SIDES) viewports[side].resetCamera(both);
}
