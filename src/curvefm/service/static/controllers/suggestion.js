// The suggested next curve: after each edit the service proposes where one more curve helps most (its ends on the
// source where the map is least certain, and where the map sends them on the target). Its ends are drawn as
// faint grey balls on both shapes, and the curve between them, traced by the session's tracer as adding it traces it,
// as a faint dashed line; "Accept suggestion" (or the A key) adds it as a curve (controllers/curves.js). To move an
// end first, click near it (within SNAP of the shape's size), then click where it belongs on the same shape: the
// service traces the curve between the ends as moved, and the line follows.
import { api } from "../api.js";
import {
  mayEdit,
  moveSuggestedEnd,
  pendingEmpty,
  setMoving,
  setShowSuggestion,
  setSuggestedPaths,
  setSuggestion,
  state,
} from "../store.js";
import { $ } from "../views/dom.js";
import { report } from "../views/messages.js";
import { SIDES, viewports } from "../views/viewports.js";

const SNAP = 0.04; // a click this close to a suggested end (a fraction of the shape's bounding diagonal) picks it
const PRIOR_POLL_MS = 600; // as the quality's: the landmark prior lands about a second after an edit
let nextRead = null; // the timer of the next read while the landmark prior is pending
let deferred = false; // the maps are about to change: the suggestion is asked for once they did (deferSuggestion)

/** Ask for the suggestion for the session's current maps and show it; an answer overtaken by another revision or
 * session is dropped. Read after the texture is drawn, in a request of its own: no edit waits for it. */
export async function refreshSuggestion() {
  const session = state.session;
  if (!session || !state.showSuggestion) return;
  clearTimeout(nextRead);
  deferred = false;
  try {
    const suggestion = await api.suggestion(session.id);
    await placeSuggestion(suggestion);
    if (state.session !== session || suggestion.revision !== session.revision) return;
    if (!state.moving) setSuggestion(suggestion); // an end being moved keeps the suggestion it belongs to
    showSuggestion();
    if (suggestion.prior_pending) nextRead = setTimeout(refreshSuggestion, PRIOR_POLL_MS);
  } catch (error) {
    if (error.kind !== "network") report(error, "No next curve could be suggested");
  }
}

/** An edit's maps will still change (its landmark prior lands about a second later): hide the previous maps'
 * suggestion now and ask for one once the prior landed (refreshDeferredSuggestion), not now. A suggestion costs
 * the service a tenth of a second or more of CPU; asked for now and again when the prior lands, both fell on the
 * next curve's clicks, on the cores that trace, solve and draw them. */
export function deferSuggestion() {
  deferred = true;
  clearTimeout(nextRead);
  if (state.suggestion === null) return;
  setSuggestion(null);
  showSuggestion();
}

/** Ask for a deferred suggestion (the prior landed, or the clicks of a curve were cancelled), unless a curve is
 * being entered or sent: its edit makes the maps change again. */
export function refreshDeferredSuggestion() {
  if (deferred && pendingEmpty() && state.editing === 0) refreshSuggestion();
}

/** Place the suggestion's ends and paths on shapes drawn as display copies (points.js). */
function placeSuggestion(suggestion) {
  return Promise.all(SIDES.map((side) => state.shapes[side].points.load([...suggestion[side], ...(suggestion[`path_${side}`] ?? [])])));
}

/** Trace the suggested curve again between its ends as the user moved them; an answer for ends moved since, or
 * for a suggestion replaced since, is dropped. */
async function retraceSuggestion() {
  const { session, suggestion } = state;
  try {
    const traced = await api.suggestion(session.id, { source: suggestion.source, target: suggestion.target });
    await placeSuggestion(traced);
    const same = SIDES.every((side) => traced[side].join() === suggestion[side].join());
    if (state.suggestion !== suggestion || !same) return;
    setSuggestedPaths(traced);
    showSuggestion();
  } catch (error) {
    if (error.kind !== "network") report(error, "The suggested curve could not be traced between these ends");
  }
}

/** Draw the suggestion on both shapes (none while it is hidden or there is none) and enable its button. */
export function showSuggestion() {
  const { suggestion, showSuggestion: shown, moving } = state;
  for (const side of SIDES) {
    const { points } = state.shapes[side] ?? {};
    const rows = shown && suggestion ? [...points.rows(suggestion[side])] : [];
    const path = shown && suggestion?.[`path_${side}`];
    viewports[side].setSuggestion(rows, moving?.side === side ? moving.index : -1, path && points.has(path) ? points.path(path) : null);
  }
  $("accept-suggestion").disabled = !(shown && suggestion && state.ready && mayEdit());
  if (moving) $("hint").textContent = `Click where this end of the suggested curve belongs on the ${moving.side}.`;
}

/** The checkbox. */
export function toggleSuggestion(show) {
  setShowSuggestion(show);
  showSuggestion();
  if (show && state.ready && state.suggestion?.revision !== state.session.revision) refreshSuggestion();
}

/** A click on a shape while a suggestion is shown and no curve is being entered: it picks a suggested end near it,
 * or places the end being moved. Returns whether the click was the suggestion's. */
export function clickSuggestion(side, vertex) {
  const { suggestion, moving } = state;
  if (!suggestion || !state.showSuggestion || !pendingEmpty()) return false;
  const { mesh, diagonal } = state.shapes[side];
  if (moving?.side === side) {
    moveSuggestedEnd(side, moving.index, mesh.fileIds[vertex]);
    showSuggestion();
    retraceSuggestion();
    return true;
  }
  const rows = viewports[side].suggestedRows;
  const distance = (row) => (row < 0 ? Infinity : Math.hypot(...[0, 1, 2].map((i) => mesh.vertices[3 * row + i] - mesh.vertices[3 * vertex + i])));
  const near = rows.map(distance);
  const index = near.indexOf(Math.min(...near));
  if (near[index] > SNAP * diagonal) return false;
  setMoving({ side, index });
  showSuggestion();
  return true;
}
