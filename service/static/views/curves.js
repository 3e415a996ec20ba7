// Curves as drawn: tubes on both viewports, the list in the Curves panel, the markers of the curve being clicked
// and the hint that says what to click next.
import { pendingEmpty, state } from "../store.js";
import { $ } from "./dom.js";
import { SIDES, viewports } from "./viewports.js";

const PALETTE = [
  "#e6194b", "#1f78ff", "#2ca02c", "#ff7f0e", "#9b30ff", "#00a6a6", "#d62fb4", "#8c564b", "#bcbd22", "#111111",
];

/** A curve keeps its colour for its whole life: the colour follows the number in its id (c1, c2, ...). */
export function curveColor(curveId) {
  const number = Number.parseInt(String(curveId).replace(/\D/g, ""), 10) || 1;
  return PALETTE[(number - 1) % PALETTE.length];
}

/** The session's curves: tubes on both shapes (the selected one thicker), the list, and the buttons that need
 * curves or edits. */
export function showCurves() {
  const { curves } = state.session;
  for (const side of SIDES) {
    const { mesh } = state.shapes[side];
    viewports[side].setCurves(
      curves.map((curve) => ({
        key: `${curve.id}:${curve.tracer}:${curve[`path_${side}`].length}`,
        color: curveColor(curve.id),
        path: curve[`path_${side}`].map((id) => mesh.fileToInternal[id]),
        emphasis: curve.id === state.selected,
      })),
    );
  }
  renderCurveList($("curve-list"), curves, state.selected);
  $("undo-button").disabled = state.history.length === 0;
  $("refine-button").disabled = curves.length === 0;
}

/** The list of curves: colour, id, tracer, path lengths, and buttons (data-action retrace, delete). */
function renderCurveList(list, curves, selectedId) {
  list.replaceChildren(
    ...curves.map((curve) => {
      const item = document.createElement("li");
      item.dataset.curveId = curve.id;
      item.classList.toggle("selected", curve.id === selectedId);
      item.title =
        `${curve.id}: traced by ${curve.tracer}, ${curve.path_source.length} vertices on the source and ` +
        `${curve.path_target.length} on the target. Click to select (drawn thicker).`;
      const swatch = document.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = curveColor(curve.id);
      const label = document.createElement("span");
      label.className = "curve-label";
      const [onSource, onTarget] = [curve.path_source.length, curve.path_target.length];
      label.textContent = `${curve.id} · ${curve.tracer} · ${onSource}/${onTarget} v`;
      label.title = `${curve.id}, traced by ${curve.tracer}: ${onSource} vertices on the source / ${onTarget} on the target`;
      const retrace = button("↻", "re-trace with the tracer chosen above", "retrace");
      item.append(swatch, label, retrace, button("✕", "delete", "delete"));
      return item;
    }),
  );
}

function button(text, title, action) {
  const element = document.createElement("button");
  element.type = "button";
  element.className = "icon";
  element.textContent = text;
  element.title = title;
  element.setAttribute("aria-label", title);
  element.dataset.action = action;
  return element;
}

/** Markers of the clicks so far (redrawing only the given sides), the hint, the cancel button. */
export function showPending(sides = SIDES) {
  const color = curveColor(`c${state.session?.next_curve ?? 1}`);
  for (const side of sides) viewports[side].setMarkers(state.pending.points[side].map((vertex) => ({ vertex, color })));
  $("hint").textContent = state.pickingRegion ? "Click the source to choose the region." : pendingHint();
  $("cancel-pending").disabled = pendingEmpty();
}

/** The hint while a finished curve is being traced (showPending replaces it). */
export function showTracing() {
  $("hint").textContent = "Tracing…";
}

/** What to click next. */
function pendingHint() {
  const { points, closed } = state.pending;
  for (const side of SIDES) {
    const count = points[side].length;
    if (closed[side]) continue;
    if (count === 0 && pendingEmpty()) {
      return "Click the start of a curve on the source (then its end), then on the target.";
    }
    if (count === 0) return `Now click the start on the ${side}, then its end.`;
    return `Click the end on the ${side}; Shift+click adds a waypoint (${count} so far).`;
  }
  return "";
}
