// What clicks on the shapes and the Curves panel do: enter a curve pair point by point, then add it; delete,
// re-trace or select a listed curve; undo; cancel the clicks so far (also Escape).
import {
  answeringTemplate,
  clearPending,
  clickPending,
  dropNewestEdit,
  mayEdit,
  pendingComplete,
  recordEdit,
  selectCurve,
  setMoving,
  setPickingRegion,
  setSuggestion,
  state,
} from "../store.js";
import { showCurves, showPending, showTracing } from "../views/curves.js";
import { tracerChoice } from "../views/forms.js";
import { readOnlyHint } from "../views/hints.js";
import { toast } from "../views/messages.js";
import { commentClick } from "./comments.js";
import { chooseRegion } from "./display.js";
import { edits, runEdit } from "./edits.js";
import { answerTemplateCurve } from "./guide.js";
import { clickSuggestion, refreshDeferredSuggestion, showSuggestion } from "./suggestion.js";

/** A click on a vertex of one shape (internal id): a point of the curve being entered, the region's centre, or (Alt, or
 * the Comment toggle) where a review comment is pinned. */
export function pickVertex(side, vertex, event) {
  if (!state.ready || commentClick(side, vertex, event)) return;
  if (state.pickingRegion) {
    if (side === "source") chooseRegion(vertex, event.timeStamp);
    return;
  }
  if (!mayEdit()) {
    refuseClick();
    return;
  }
  if (!answeringTemplate() && clickSuggestion(side, vertex)) return;
  const answering = answeringTemplate();
  clickPending(side, vertex, event.shiftKey);
  if (answering && side === "target" && state.pending.closed.target) answerTemplateCurve(event.timeStamp);
  else if (pendingComplete()) addCurve(event.timeStamp);
  else showPending([side]);
}

let refusedIn = null; // the session whose clicks were refused with a toast: once is enough, the hint stays

function refuseClick() {
  if (refusedIn === state.session.id) return;
  refusedIn = state.session.id;
  toast(readOnlyHint());
}

function fileIds(side, internalIds) {
  return internalIds.map((vertex) => state.shapes[side].mesh.fileIds[vertex]);
}

function addCurve(clickTime) {
  const spec = {
    source: fileIds("source", state.pending.points.source),
    target: fileIds("target", state.pending.points.target),
    ...tracerChoice(),
  };
  clearPending(); // its markers stay until the traced curve replaces them, in the frame with the new texture
  showTracing();
  return runEdit(clickTime, "add", "The curve was not added", async () => {
    const edit = await edits.add(spec);
    recordEdit("add", edit.curve);
    return edit;
  });
}

function removeCurve(curveId, clickTime) {
  const position = state.session.curves.findIndex((c) => c.id === curveId);
  const curve = state.session.curves[position];
  return runEdit(clickTime, "delete", `Curve ${curveId} was not deleted`, async () => {
    const edit = await edits.remove(curveId);
    recordEdit("remove", curve, position);
    return edit;
  });
}

function retraceCurve(curveId, clickTime) {
  const previous = state.session.curves.find((c) => c.id === curveId);
  const spec = { ...previous.spec, ...tracerChoice() };
  return runEdit(clickTime, "re-trace", `Curve ${curveId} was not re-traced`, async () => {
    const edit = await edits.replace(curveId, spec);
    recordEdit("replace", previous);
    return edit;
  });
}

/** A click in the curve list: its ↻ re-traces the curve with the chosen tracer, its ✕ deletes it, elsewhere
 * the curve is selected (drawn thicker), or unselected when it was. */
export function clickCurveList(event) {
  const item = event.target.closest("li[data-curve-id]");
  if (!item) return;
  const { curveId } = item.dataset;
  const action = event.target.closest("button")?.dataset.action;
  if (action === "retrace") retraceCurve(curveId, event.timeStamp);
  else if (action === "delete") removeCurve(curveId, event.timeStamp);
  else {
    selectCurve(item.classList.contains("selected") ? null : curveId);
    showCurves();
  }
}

export function undo(clickTime) {
  if (state.history.length === 0) return null;
  return runEdit(clickTime, "undo", "The last edit could not be undone", undoNewest);
}

/** Reverse the newest edit and resolve to the service's answer. When the service refuses, the edit stays in the
 * history, so it can be tried again. A deleted curve comes back with its id (so its colour) at its place. */
async function undoNewest() {
  const entry = state.history.at(-1);
  let edit;
  if (entry.kind === "add") {
    edit = await edits.remove(entry.curveId);
  } else if (entry.kind === "remove") {
    edit = await edits.add(entry.spec, { curveId: entry.curveId, position: entry.position });
  } else {
    edit = await edits.replace(entry.curveId, entry.spec);
  }
  dropNewestEdit();
  return edit;
}

/** Add the suggested curve (ends as moved) with the chosen tracer. */
export function acceptSuggestion(clickTime) {
  const { suggestion } = state;
  if (!suggestion || !state.showSuggestion || !state.ready || !mayEdit()) return null;
  const spec = { source: [...suggestion.source], target: [...suggestion.target], ...tracerChoice() };
  setSuggestion(null);
  showSuggestion();
  return runEdit(clickTime, "add", "The suggested curve was not added", async () => {
    const edit = await edits.add(spec);
    recordEdit("add", edit.curve);
    return edit;
  });
}

export function cancelPending() {
  clearPending();
  showPending();
  refreshDeferredSuggestion(); // it waited for the curve being entered
}

/** Escape cancels the clicks so far (and choosing a region, and moving a suggested end); Ctrl+Z (Cmd+Z) undoes; A
 * accepts the suggested curve. Not while typing. */
export function pressKey(event) {
  if (event.target.closest("input, select, textarea")) return;
  if (event.key === "Escape") {
    clearPending();
    setPickingRegion(false);
    setMoving(null);
    showPending();
    showSuggestion();
    refreshDeferredSuggestion();
  } else if (event.key === "a" && !event.ctrlKey && !event.metaKey && !event.altKey) {
    acceptSuggestion(event.timeStamp);
  } else if ((event.ctrlKey || event.metaKey) && event.key === "z" && state.ready) {
    event.preventDefault();
    undo(performance.now());
  }
}
