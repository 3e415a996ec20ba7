// The live maps' quality, without ground truth: after every change the service measures how far each vertex
// lands from itself on the round trip target -> source -> target; the score goes to the status line and, while
// the overlay is on, the drift tints the target and the weakest regions are ringed on both shapes.
import { api } from "../api.js";
import { setQuality, setShowQuality, state } from "../store.js";
import { report } from "../views/messages.js";
import { showStatus } from "../views/page.js";
import { repaint, showWeakestRegions } from "../views/viewports.js";

/** Ask for the quality of the session's current maps and show it; an answer overtaken by a newer revision or
 * another session is dropped. Runs after the new texture is drawn, so it never delays a click's texture. */
export async function refreshQuality() {
  const session = state.session;
  if (!session) return;
  try {
    const quality = await api.quality(session.id);
    const { source, target } = state.shapes; // the weakest vertices are ringed at the drawn vertex nearest to them
    await Promise.all([source.points.load([quality.worstSource]), target.points.load([quality.worstTarget])]);
    if (state.session !== session || quality.revision < (state.quality?.revision ?? -1)) return;
    setQuality(quality);
    showStatus();
    if (state.showQuality) showOverlay();
  } catch (error) {
    report(error, "The map's quality could not be measured");
  }
}

/** The overlay checkbox. */
export async function toggleQuality(show) {
  setShowQuality(show);
  if (!state.ready) return;
  showOverlay();
  if (show && state.quality?.revision !== state.session.revision) await refreshQuality();
}

function showOverlay() {
  showWeakestRegions();
  repaint("target");
}
