// The live maps' quality, without ground truth: after every change the service measures how far each vertex
// lands from itself on the round trip target -> source -> target; the score goes to the status line and, while
// the overlay is on, the drift tints the target and the weakest regions are ringed on both shapes. The status
// line also says what the map is (its energy and size, and why), which an edit's answer carries.
import { api } from "../api.js";
import { setQuality, setShowQuality, setSolve, state } from "../store.js";
import { report } from "../views/messages.js";
import { showQualityLegend, showStatus } from "../views/page.js";
import { repaint, showWeakestRegions } from "../views/viewports.js";

const PRIOR_POLL_MS = 600; // the landmark prior lands about a second after an edit
const FOLLOWED_PRIOR_POLL_MS = 3000; // a page following the session's events is told when it lands (live.js)
const OFFLINE_RETRY_MS = 2000; // as the health check: the figures come back with the service
let nextRead = null; // the timer of the next read while the landmark prior is pending

/** Ask for the quality of the session's current maps and show it; an answer overtaken by a newer revision or
 * another session is dropped. Runs after the new texture is drawn, so it never delays a click's texture. While
 * the answer says the landmark prior is still to land, the figures are marked as updating and read again. */
export async function refreshQuality() {
  const session = state.session;
  if (!session) return;
  clearTimeout(nextRead);
  try {
    const quality = await api.quality(session.id);
    const { source, target } = state.shapes; // the weakest vertices are ringed at the drawn vertex nearest to them
    await Promise.all([source.points.load([quality.worstSource]), target.points.load([quality.worstTarget])]);
    if (state.session !== session || overtaken(quality)) return;
    setQuality(quality);
    showStatus(); // and the overlay's legend
    if (state.showQuality) showOverlay();
    const wait = state.followed === session.id ? FOLLOWED_PRIOR_POLL_MS : PRIOR_POLL_MS;
    if (quality.priorPending) nextRead = setTimeout(refreshQuality, wait);
  } catch (error) {
    // the banner says that the service cannot be reached: a toast for each read in the background would only
    // pile up over the shapes
    if (error.kind === "network") nextRead = setTimeout(refreshQuality, OFFLINE_RETRY_MS);
    else report(error, "The map's quality could not be measured");
  }
}

/** A quality answer older than the one shown: of an older revision, or of the same one before its prior landed. */
function overtaken(quality) {
  const shown = state.quality;
  if (!shown) return false;
  return quality.revision < shown.revision || (quality.revision === shown.revision && quality.priorPending && !shown.priorPending);
}

/** Ask what the session's maps are now (energy, weights, size, why) and show it in the status line. */
export async function refreshSolve() {
  const session = state.session;
  if (!session) return;
  try {
    const solve = await api.solve(session.id);
    if (state.session !== session) return;
    setSolve(solve);
    showStatus();
  } catch (error) {
    report(error, "The map's energy and size could not be read");
  }
}

/** The overlay checkbox. */
export async function toggleQuality(show) {
  setShowQuality(show);
  showQualityLegend();
  if (!state.ready) return;
  showOverlay();
  if (show && state.quality?.revision !== state.session.revision) await refreshQuality();
}

function showOverlay() {
  showWeakestRegions();
  repaint("target");
}
