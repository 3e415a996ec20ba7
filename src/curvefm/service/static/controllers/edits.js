// Curve edits sent to the service. Each keeps the local session record in step with the service's answer;
// runEdit shows an edit and times it from the click to the frame that shows the new texture.
import { api } from "../api.js";
import {
  answerOf,
  curveAdded,
  curveRemoved,
  curveReplaced,
  editEnded,
  editStarted,
  recordSample,
  setMap,
  setRevision,
  setSolve,
  state,
} from "../store.js";
import { placeCurves, showCurves, showPending } from "../views/curves.js";
import { report } from "../views/messages.js";
import { showMapChoice, showSessionEntry, showStatus } from "../views/page.js";
import { paint, viewports } from "../views/viewports.js";
import { refreshCollection } from "./collections.js";
import { resync } from "./connection.js";
import { carriedFromAnswer, carriedFunction } from "./feedback.js";
import { refreshQuality } from "./quality.js";
import { deferSuggestion, refreshSuggestion } from "./suggestion.js";

/** The session's edits: call the service, then keep the local record in step with its answer. */
export const edits = {
  /** place: { curveId, position } of a deleted curve brought back (undo), else a new curve at the end. */
  async add(spec, place = {}) {
    const edit = await api.addCurve(state.session.id, state.session.revision, spec, { ...place, carry: carry() });
    curveAdded(edit.curve, place.position ?? undefined);
    return edit;
  },
  async remove(curveId) {
    const edit = await api.deleteCurve(state.session.id, state.session.revision, curveId, carry());
    curveRemoved(curveId);
    return edit;
  },
  async replace(curveId, spec) {
    const edit = await api.replaceCurve(state.session.id, state.session.revision, curveId, spec, carry());
    curveReplaced(curveId, edit.curve);
    return edit;
  },
  /** answer: { template_curve, target, tracer, tracer_params } on the guided member; replaces an earlier answer. */
  async answer(answer) {
    const previous = answerOf(answer.template_curve);
    const { collection, member, annotator } = state.guide;
    const edit = await api.answerCurve(collection, member, state.session.revision, answer, annotator);
    if (previous) curveReplaced(previous.id, edit.curve);
    else curveAdded(edit.curve);
    return edit;
  },
};

/** What an edit's answer should carry: the function the target shows, unless it needs a region (the indicator),
 * which the transfer read after the edit brings. */
function carry() {
  return state.fn === "indicator" ? null : state.fn;
}

let lastEdit = Promise.resolve();

/** Edits go to the service one after another: each is based on the revision the one before left (If-Match), so a
 * quick second click is not refused as stale. */
function inTurn(perform) {
  const turn = lastEdit.then(perform);
  lastEdit = turn.catch(() => {});
  return turn;
}

/** Run one edit (perform resolves to the service's answer), show it, and time it from the click to the frame
 * that shows the new texture; ``failure`` starts the message when it fails. The curves and the texture change
 * in one frame: a software renderer pays for every frame. While it runs, changes announced by the service wait
 * (state.editing): the edit's own answer brings the revision they may be about. */
export async function runEdit(clickTime, kind, failure, perform) {
  const sessionId = state.session.id;
  editStarted();
  try {
    const edit = await inTurn(perform);
    const editedAt = performance.now();
    if (state.session?.id !== sessionId) return;
    setRevision(edit.map.revision);
    setSolve(edit.map.solve);
    if (state.map === "pointwise") setMap("functional"); // the refined map belongs to an older revision
    showMapChoice();
    showSessionEntry();
    // the new paths drawn with the texture; the answer carries it unless the page asked for another function since
    const answered = edit.carried?.function === state.fn;
    const shown = answered ? carriedFromAnswer(edit.carried) : carriedFunction();
    const [carried] = await Promise.all([shown, placeCurves()]);
    const fetchedAt = performance.now();
    showCurves();
    showPending();
    if (carried === null) return; // a newer edit's texture is on its way
    if (carried.priorPending) deferSuggestion(); // in the frame of the texture
    paint("target", state.fn, carried.rows);
    const drawnAt = await viewports.target.drawn();
    recordSample({
      kind,
      revision: edit.map.revision,
      totalMs: drawnAt - clickTime,
      editMs: editedAt - clickTime,
      transferMs: fetchedAt - editedAt,
      drawMs: drawnAt - fetchedAt,
      solveMs: carried.solveMs,
      requests: answered ? 1 : 2, // the edit alone, or the edit and the transfer read
    });
    refreshQuality(); // after the texture: the reverse map it needs is solved while the user looks
    if (!carried.priorPending) refreshSuggestion(); // a request of its own, after the texture too
  } catch (error) {
    showPending();
    report(error, failure);
    if (error.kind === "not_found" || error.kind === "conflict") await resync();
  } finally {
    showStatus();
    if (state.guide) refreshCollection(); // the member's progress in the Collections panel
    editEnded();
  }
}
