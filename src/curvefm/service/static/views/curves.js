// Curves as drawn: tubes on both viewports, the list in the Curves panel, the markers of the curve being clicked
// and the hint that says what to click next.
import { answeringTemplate, mayEdit, pendingEmpty, state, templateCurves } from "../store.js";
import { showGuide, showTemplateButton } from "./collections.js";
import { $ } from "./dom.js";
import { curveColor, pendingHint } from "./hints.js";
import { report } from "./messages.js";
import { SIDES, viewports } from "./viewports.js";

/** The session's curves: tubes on both shapes (the selected one thicker), the list, and the buttons that need
 * curves or edits. On a guided member the source also shows the template curves not answered yet, and the
 * current template curve is drawn thicker. A path through vertices a display copy does not draw is drawn once
 * the service has placed them (placeCurves). */
export function showCurves() {
  const { curves } = state.session;
  const current = state.guide?.current;
  let unplaced = false;
  for (const side of SIDES) {
    const { points } = state.shapes[side];
    const tubes = curves.map((curve) => ({
      key: `${curve.id}:${curve.tracer}:${curve[`path_${side}`].length}`,
      color: curveColor(colorId(curve)),
      path: curve[`path_${side}`],
      emphasis: curve.id === state.selected || Boolean(current && curve.spec.template_curve === current),
    }));
    if (side === "source") tubes.push(...unansweredTemplateTubes(current));
    const placed = tubes.filter((tube) => points.has(tube.path));
    unplaced ||= placed.length < tubes.length;
    viewports[side].setCurves(placed.map((tube) => ({ ...tube, points: points.path(tube.path) })));
  }
  renderCurveList($("curve-list"), curves, state.selected);
  $("undo-button").disabled = state.history.length === 0;
  $("refine-button").disabled = curves.length === 0;
  showTemplateButton();
  showGuide();
  if (unplaced) placeCurves().then(showAgain(state.session), (error) => report(error, "The curves could not be drawn"));
}

/** Ask the service where the vertices of every curve path (and template curve) are that the shapes' display copies
 * do not draw; resolves at once for shapes drawn whole. */
export function placeCurves() {
  const { curves } = state.session;
  const loads = SIDES.map((side) => state.shapes[side].points.load(curves.flatMap((c) => c[`path_${side}`])));
  loads.push(state.shapes.source.points.load(templateCurves().flatMap((curve) => curve.path)));
  return Promise.all(loads);
}

/** Show the curves and the clicks again (their places are known now), if ``session`` is still the one shown. */
function showAgain(session) {
  return () => {
    if (state.session !== session) return;
    showCurves();
    showPending();
  };
}

/** A curve answering a template curve takes the template curve's colour, on every member alike. */
function colorId(curve) {
  return curve.spec.template_curve ?? curve.id;
}

function unansweredTemplateTubes(current) {
  return templateCurves()
    .filter((curve) => !curve.answer)
    .map((curve) => ({
      key: `template:${curve.id}`,
      color: curveColor(curve.id),
      path: curve.path,
      emphasis: curve.id === current,
    }));
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
      swatch.style.background = curveColor(colorId(curve));
      const label = document.createElement("span");
      label.className = "curve-label";
      const [onSource, onTarget] = [curve.path_source.length, curve.path_target.length];
      const answers = curve.spec.template_curve ? ` → ${curve.spec.template_curve}` : "";
      label.textContent = `${curve.id}${answers} · ${curve.tracer} · ${onSource}/${onTarget} v`;
      label.title = `${curve.id}, traced by ${curve.tracer}: ${onSource} vertices on the source / ${onTarget} on the target`;
      const retrace = button("↻", "re-trace with the tracer chosen above", "retrace");
      const remove = button("✕", "delete", "delete");
      retrace.disabled = remove.disabled = !mayEdit();
      item.append(swatch, label, retrace, remove);
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

/** Markers of the clicks so far (redrawing only the given sides; on a guided member the start of the current
 * template curve is marked on the source), the hint, the cancel button. */
export function showPending(sides = SIDES) {
  const color = answeringTemplate() ? curveColor(state.guide.current) : curveColor(`c${state.session?.next_curve ?? 1}`);
  for (const side of sides) {
    const markers = state.pending.points[side].map((vertex) => ({ vertex, color }));
    const start = side === "source" && answeringTemplate() ? templateStart(state.guide.current) : { vertex: -1 };
    if (start.vertex >= 0) markers.push(start);
    viewports[side].setMarkers(markers);
  }
  $("hint").textContent = state.pickingRegion ? "Click the source to choose the region." : pendingHint();
  $("cancel-pending").disabled = pendingEmpty();
  showGuide();
}

/** The start of a template curve: at the drawn vertex nearest to it (-1 until the service placed it). */
function templateStart(curveId) {
  const curve = templateCurves().find((c) => c.id === curveId);
  return { vertex: state.shapes.source.points.rows([curve.path[0]])[0], color: curveColor(curveId) };
}

/** The hint while a finished curve is being traced (showPending replaces it). */
export function showTracing() {
  $("hint").textContent = "Tracing…";
}
