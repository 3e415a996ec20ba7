// What the View panel's controls do: the carried function (texture, coordinates, a region picked on the source),
// the map it goes through, the texture image, cameras and curve tubes.
import { regionAround } from "../functions.js";
import { setFunction, setMap, setPickingRegion, setRegion, setTexture, state } from "../store.js";
import { imageTexture } from "../views/colors.js";
import { showPending } from "../views/curves.js";
import { $ } from "../views/dom.js";
import { report, toast } from "../views/messages.js";
import { showRegionControls } from "../views/page.js";
import { orientViews, SIDES, viewports } from "../views/viewports.js";
import { showFeedback } from "./feedback.js";

/** fn: uv (texture), xyz (coordinates as colour), indicator (a region: the next click on the source picks it
 * unless one is chosen). */
export function selectFunction(fn) {
  setFunction(fn);
  showRegionControls();
  showPending();
  showFeedback();
}

/** The region of the Radius control around a source vertex (internal id). */
export function chooseRegion(center, clickTime) {
  const { mesh, diagonal } = state.shapes.source;
  const radius = (Number($("region-radius").value) / 100) * diagonal;
  const { ids, indicator } = regionAround(mesh.vertices, center, radius);
  setRegion({ center, indicator, fileIds: ids.map((i) => mesh.fileIds[i]) });
  showPending();
  showFeedback(clickTime, "region");
}

export function changeRegionRadius(clickTime) {
  if (state.region) chooseRegion(state.region.center, clickTime);
}

/** "Pick on source": the next click on the source chooses the region. */
export function pickRegion() {
  setPickingRegion(true);
  showPending();
}

/** map: functional (the live map) or pointwise (the last refinement's). */
export function selectMap(map, clickTime) {
  setMap(map);
  showFeedback(clickTime, "map");
}

/** The image the texture function carries, from a file input. */
export async function useTextureImage(input) {
  const [file] = input.files;
  if (!file) return;
  try {
    setTexture(await imageTexture(file));
    if (!state.shapes.source?.info.has_uv) {
      toast("The source has no texture coordinates of its own: the image is laid on generated cylindrical ones.");
    }
    if (state.ready) showFeedback();
  } catch (error) {
    report(error, "The texture image could not be used");
  } finally {
    input.value = "";
  }
}

/** Up axis changed, or Reset view: turn and frame both shapes again. */
export function reorient() {
  if (state.ready) orientViews();
}

/** Orbiting one viewport moves the other's camera too while Link cameras is checked. */
export function followCameras() {
  let following = false;
  for (const [side, other] of [["source", "target"], ["target", "source"]]) {
    viewports[side].controls.addEventListener("change", () => {
      if (following || !$("link-cameras").checked) return;
      following = true;
      viewports[other].copyCamera(viewports[side]);
      following = false;
    });
  }
}

/** Link cameras checked: the target takes the source's camera. */
export function linkCameras(linked) {
  if (linked && state.ready) viewports.target.copyCamera(viewports.source);
}

export function showCurveTubes(visible) {
  for (const side of SIDES) viewports[side].showCurves(visible);
}
