// What the surfaces show after every change: the chosen source function carried to the target, through the live
// map from the service or through the refined pointwise map, timed from the click that asked for it.
import { api, decodeCarried } from "../api.js";
import { pullBack } from "../functions.js";
import { nextTransferTicket, recordSample, state } from "../store.js";
import { report } from "../views/messages.js";
import { showStatus } from "../views/page.js";
import { paint, showSource, sourceValues, viewports } from "../views/viewports.js";
import { refreshDeferredSuggestion } from "./suggestion.js";

const COLUMNS = { uv: 2, xyz: 3, indicator: 1 };
const PRIOR_POLL_MS = 600; // the landmark prior takes about a second after an edit
// a page that follows the session's events hears when the prior lands (priorLanded): its reads are a fallback
const FOLLOWED_PRIOR_POLL_MS = 3000;
let awaited = null; // { ticket, timer }: the texture to show again once the landmark prior has landed

/** The chosen function carried to the target (rows per target vertex), through the live map from the service
 * or through the refined pointwise map; null when a newer request started meanwhile (its answer wins). */
export async function carriedRows() {
  const carried = await carriedFunction();
  return carried && carried.rows;
}

/** carriedRows with the time the service spent solving the map for it and whether the landmark prior is still to
 * land: { rows, solveMs, priorPending } or null. */
export async function carriedFunction() {
  const ticket = nextTransferTicket();
  const { fn } = state;
  if (fn === "indicator" && !state.region) {
    return { rows: new Float32Array(state.shapes.target.mesh.nVertices), solveMs: 0 };
  }
  if (state.map === "pointwise") {
    return { rows: pullBack(sourceValues(fn), COLUMNS[fn], state.pointwise.p2p), solveMs: 0 };
  }
  const vertices = fn === "indicator" ? state.region.fileIds : null;
  const { values, solveMs, priorPending } = await api.transfer(state.session.id, fn, vertices);
  if (ticket !== state.transferTicket) return null;
  if (priorPending) showWhenPriorLands(ticket);
  return { rows: values, solveMs, priorPending };
}

/** carriedFunction from an edit's answer that carried it (no read): { rows, solveMs, priorPending }. */
export function carriedFromAnswer(carried) {
  const ticket = nextTransferTicket();
  const { values, solveMs, priorPending } = decodeCarried(carried);
  if (priorPending) showWhenPriorLands(ticket);
  return { rows: values, solveMs, priorPending };
}

/** The service is still computing the landmark prior for the current curves: show the better map when it lands
 * (unless something newer has been asked for meanwhile), and then the suggestion deferred for it. Until then the
 * map is the one on screen, so a read that finds the prior still pending paints nothing: repainting 28k vertices
 * took the cores from the next clicks. A page following the session's events reads when told (priorLanded). */
function showWhenPriorLands(ticket) {
  clearTimeout(awaited?.timer);
  const wait = state.followed === state.session?.id ? FOLLOWED_PRIOR_POLL_MS : PRIOR_POLL_MS;
  awaited = { ticket, timer: setTimeout(() => showLandedPrior(ticket), wait) };
}

async function showLandedPrior(ticket) {
  if (ticket !== state.transferTicket) return;
  awaited = null;
  try {
    const carried = await carriedFunction(); // still pending: it waits again (showWhenPriorLands)
    if (carried === null || carried.priorPending) return;
    paint("target", state.fn, carried.rows);
    refreshDeferredSuggestion();
  } catch {
    // a refresh in the background: a lost connection has its banner, and the next change shows the map
  }
}

/** The session's events say that the landmark prior of ``revision`` landed: show the map it improved. */
export function priorLanded(revision) {
  if (revision !== state.session?.revision || state.editing > 0) return;
  if (awaited === null) {
    refreshDeferredSuggestion();
    return;
  }
  clearTimeout(awaited.timer);
  showLandedPrior(awaited.ticket);
}

/** Paint the source and the carried function on the target; with the click's time, record how long it took
 * (a sample of ``kind``: region, map). */
export async function showFeedback(clickTime = null, kind = "view") {
  try {
    showSource();
    const rows = await carriedRows();
    if (rows === null) return;
    const fetchedAt = performance.now();
    paint("target", state.fn, rows);
    if (clickTime === null) return;
    const drawnAt = await viewports.target.drawn();
    recordSample({
      kind,
      revision: state.session.revision,
      totalMs: drawnAt - clickTime,
      editMs: 0,
      transferMs: fetchedAt - clickTime,
      drawMs: drawnAt - fetchedAt,
    });
    showStatus();
  } catch (error) {
    report(error, "The target could not be updated");
  }
}
