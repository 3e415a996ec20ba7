// The page around the viewports, from the store: the top bar (title, status line), the loading message, the
// session and shape lists, and the state of the panels' controls.
import { mayEdit, mayManage, state } from "../store.js";
import { $ } from "./dom.js";

/** The message over the viewports (text), or none (null). */
export function showLoading(text) {
  const element = $("loading");
  element.hidden = text === null;
  element.textContent = text ?? "";
}

/** The status line: the session's revision and curves, the shapes drawn as display copies, and the timing of the
 * last click. */
export function showStatus() {
  const parts = [];
  if (state.session) parts.push(`revision ${state.session.revision}`, `${state.session.curves.length} curves`);
  const coarse = ["source", "target"].filter((side) => state.shapes[side]?.mesh.displayCopy);
  if (coarse.length) parts.push(`display copy: ${coarse.map(drawnShare).join(", ")} vertices`);
  if (state.quality) parts.push(`round-trip drift ${(100 * state.quality.score).toFixed(1)}% of √area`);
  const last = state.stats.last;
  if (last) {
    parts.push(
      `click→texture ${last.totalMs.toFixed(0)} ms (${last.kind}: edit ${last.editMs.toFixed(0)} · transfer ` +
        `${last.transferMs.toFixed(0)} · draw ${last.drawMs.toFixed(0)})`,
    );
    if (last.solveMs !== undefined) parts.push(`solve ${last.solveMs.toFixed(1)} ms`);
  }
  $("status-line").textContent = parts.join(" · ");
}

/** "target 49,991 of 110,210": how many of a shape's vertices its display copy draws. */
function drawnShare(side) {
  const { nVertices, shapeVertices } = state.shapes[side].mesh;
  return `${side} ${nVertices.toLocaleString("en")} of ${shapeVertices.toLocaleString("en")}`;
}

/** The shape and session lists (GET /shapes, GET /sessions), keeping what is chosen. */
export function showLists(shapes, sessions) {
  for (const [select, role] of [[$("source-select"), "source"], [$("target-select"), "target"]]) {
    const previous = select.value || state.session?.[role];
    select.replaceChildren(
      ...shapes.map((s) => {
        const label = `${s.name} (${s.n_vertices.toLocaleString("en")} vertices)`;
        return Object.assign(new Option(label, s.id), { title: label });
      }),
    );
    if (shapes.some((s) => s.id === previous)) select.value = previous;
  }
  if (!state.session && shapes.length > 1 && !state.targetChosen) $("target-select").selectedIndex = 1;
  const sessionSelect = $("session-select");
  sessionSelect.replaceChildren(new Option("—", ""), ...sessions.map((s) => new Option(sessionLabel(s), s.id)));
  sessionSelect.value = state.session?.id ?? "";
}

function sessionLabel(summary) {
  return `${summary.name || summary.id} · ${summary.n_curves} curves · k=${summary.k}${ownedBy(summary)}`;
}

/** The open session's entry in the session list follows its curves. */
export function showSessionEntry() {
  const { session } = state;
  const option = [...$("session-select").options].find((o) => o.value === session?.id);
  if (option) option.textContent = sessionLabel({ ...session, n_curves: session.curves.length });
}

/** " · by alice" for a session of another user. */
function ownedBy(session) {
  return session.owner && session.owner !== state.user?.name ? ` · by ${session.owner}` : "";
}

/** The open session in the lists and the title. */
export function showSessionTitle() {
  const { session } = state;
  const [source, target] = [state.shapes.source.info, state.shapes.target.info];
  $("session-select").value = session.id;
  $("source-select").value = session.source;
  $("target-select").value = session.target;
  const readOnly = mayEdit() ? "" : ` · read-only (shared by ${session.owner})`;
  $("session-title").textContent =
    `${session.name || session.id}: ${source.name} → ${target.name} · k=${session.k}${readOnly}`;
}

/** The sharing select: the open session's sharing, changeable by its owner or an admin. */
export function showSharing() {
  const select = $("sharing-select");
  select.value = state.session?.sharing ?? "private";
  select.disabled = !mayManage();
}

export function openPairPanel() {
  $("pair-panel").open = true;
}

export function showPairInProgress() {
  $("open-pair").disabled = state.pairInProgress;
}

/** The region radius slider's value, in % of the source's size. */
export function showRadius(percent) {
  $("region-radius-value").textContent = `${percent}% of the size`;
}

export function showRegionControls() {
  $("region-controls").hidden = state.fn !== "indicator";
}

/** The Map choice: pointwise once a refinement gave a map, and which map is shown; the refinement's results
 * are marked stale once the curves changed after it. */
export function showMapChoice() {
  const { pointwise } = state;
  const radio = document.querySelector('input[name="map"][value="pointwise"]');
  radio.disabled = !pointwise;
  const stale = pointwise && pointwise.revision !== state.session?.revision;
  const now = stale ? ` — stale: the curves changed since (now revision ${state.session.revision})` : "";
  $("pointwise-label").textContent = pointwise
    ? `Pointwise (${pointwise.converter}, revision ${pointwise.revision}${now})`
    : "Pointwise (refine first)";
  const note = $("refine-note");
  note.hidden = !pointwise;
  note.textContent = pointwise ? `Results of revision ${pointwise.revision}${now}.` : "";
  note.classList.toggle("stale", Boolean(stale));
  document.querySelector(`input[name="map"][value="${state.map}"]`).checked = true;
}

export function enableRefine(enabled) {
  $("refine-button").disabled = !enabled;
}

/** The Cancel button of the refinement shows while its job runs. */
export function showRefineJob() {
  $("cancel-refine").hidden = state.refineJob === null;
}
