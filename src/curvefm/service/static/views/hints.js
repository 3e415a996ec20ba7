// What every panel says about curves: a curve's colour, and the hint that says what to click next (the Curves
// panel's hint and the guide's prompt on a collection member both show it).
import { answeringTemplate, mayEdit, pendingEmpty, state, templateCurves } from "../store.js";
import { SIDES } from "./viewports.js";

const PALETTE = [
  "#e6194b", "#1f78ff", "#2ca02c", "#ff7f0e", "#9b30ff", "#00a6a6", "#d62fb4", "#8c564b", "#bcbd22", "#111111",
];

/** A curve keeps its colour for its whole life: the colour follows the number in its id (c1, c2, ...). */
export function curveColor(curveId) {
  const number = Number.parseInt(String(curveId).replace(/\D/g, ""), 10) || 1;
  return PALETTE[(number - 1) % PALETTE.length];
}

/** What to click next: on a guided member, the prompt for the current template curve; on a session the user may
 * only read, that clicks add no curves. */
export function pendingHint() {
  if (state.session && !mayEdit()) return readOnlyHint();
  if (answeringTemplate()) return templatePrompt();
  if (state.guide && pendingEmpty()) {
    if (templateCurves().every((curve) => curve.answer)) {
      return "Every template curve is answered on this member: go on with \"Next member\" (or click source then target for an extra curve).";
    }
    return "Skipped template curves are left: pick one in the Collections panel, or go on with \"Next member\".";
  }
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

/** "t2 'spine': click its start on the member" (or its end, with the waypoints so far). */
function templatePrompt() {
  const curve = templateCurves().find((c) => c.id === state.guide.current);
  const name = `${curve.id}${curve.name ? ` '${curve.name}'` : ""}`;
  const again = curve.answer ? " (answered: this replaces it)" : "";
  const count = state.pending.points.target.length;
  if (count === 0) return `${name}: click its start on the member (the ball on the template marks it)${again}.`;
  return `${name}: click its end on the member; Shift+click adds a waypoint (${count} so far)${again}.`;
}

/** Said before the first click on a session shared read-only (the service would refuse its curves). */
export function readOnlyHint() {
  const owner = state.session.owner || "its owner";
  return `Read-only: ${owner} shares this session for reading, so clicks add no curves (open a session of your own on these shapes to add some).`;
}
