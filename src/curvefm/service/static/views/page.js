// The page around the viewports, from the store: the top bar (title, status line), the loading message, the
// session and shape lists, and the state of the panels' controls.
import { mayEdit, mayManage, qualityStale, state } from "../store.js";
import { $ } from "./dom.js";

/** The message over the viewports (text), or none (null). */
export function showLoading(text) {
  const element = $("loading");
  element.hidden = text === null;
  element.textContent = text ?? "";
}

/** The status line: the session's revision and curves, what its map is (energy and size; why in the tooltip), the
 * shapes drawn as display copies, the round-trip drift (greyed, "updating…", while a newer map is on its way), and
 * the timing of the last click. */
export function showStatus() {
  const parts = [];
  if (state.session) parts.push(`revision ${state.session.revision}`, `${state.session.curves.length} curves`);
  if (state.solve) parts.push(state.solve.summary);
  const coarse = ["source", "target"].filter((side) => state.shapes[side]?.mesh.displayCopy);
  if (coarse.length) parts.push(`display copy: ${coarse.map(drawnShare).join(", ")} vertices`);
  if (state.quality) parts.push(driftFigure());
  const last = state.stats.last;
  if (last) {
    parts.push(
      `click→texture ${last.totalMs.toFixed(0)} ms (${last.kind}: edit ${last.editMs.toFixed(0)} · transfer ` +
        `${last.transferMs.toFixed(0)} · draw ${last.drawMs.toFixed(0)})`,
    );
    if (last.solveMs !== undefined) parts.push(`solve ${last.solveMs.toFixed(1)} ms`);
  }
  const line = $("status-line");
  line.replaceChildren(...parts.flatMap((part, i) => (i ? [" · ", part] : [part])));
  line.title = state.solve ? `The map: ${state.solve.reason}.` : "";
  showQualityLegend();
}

function driftFigure() {
  const stale = qualityStale();
  const figure = document.createElement("span");
  figure.id = "status-drift";
  figure.classList.toggle("stale", stale);
  figure.textContent = `round-trip drift ${(100 * state.quality.score).toFixed(1)}% of √area${stale ? " (updating…)" : ""}`;
  return figure;
}

/** The overlay's legend, while the overlay is on; greyed with "updating…" while a newer map is on its way. */
export function showQualityLegend() {
  const legend = $("quality-legend");
  legend.hidden = !state.showQuality;
  const stale = qualityStale() || !state.quality;
  legend.classList.toggle("stale", stale);
  $("quality-legend-state").textContent = stale ? "updating…" : `revision ${state.quality.revision}`;
}

/** "target 49,991 of 110,210": how many of a shape's vertices its display copy draws. */
function drawnShare(side) {
  const { nVertices, shapeVertices } = state.shapes[side].mesh;
  return `${side} ${nVertices.toLocaleString("en")} of ${shapeVertices.toLocaleString("en")}`;
}

/** The value of the session list's entry that lists more sessions. */
export const MORE_SESSIONS = "more-sessions";

/** The shape and session lists (GET /shapes in its order: by name, then upload time; a page of GET /sessions with
 * `more` not listed), keeping what is chosen. */
export function showLists(shapes, sessions, more = 0) {
  for (const [select, role] of [[$("source-select"), "source"], [$("target-select"), "target"]]) {
    const previous = select.value || state.session?.[role];
    select.replaceChildren(
      ...shapes.map((s) => {
        const uploaded = s.uploaded_at ? `, ${changedAt(s.uploaded_at)}` : "";
        const label = `${s.name} (${s.n_vertices.toLocaleString("en")} vertices${uploaded})`;
        return Object.assign(new Option(label, s.id), { title: label });
      }),
    );
    if (shapes.some((s) => s.id === previous)) select.value = previous;
  }
  if (!state.session && shapes.length > 1 && !state.targetChosen) $("target-select").selectedIndex = 1;
  const sessionSelect = $("session-select");
  const entries = sessions.map(sessionOption);
  if (more > 0) entries.push(new Option(`… ${more.toLocaleString("en")} more`, MORE_SESSIONS));
  sessionSelect.replaceChildren(new Option("—", ""), ...entries);
  listOpenSession();
  sessionSelect.value = state.session?.id ?? "";
}

/** The open session has an entry in the session list even when it is older than the page listed. */
function listOpenSession() {
  const { session } = state;
  const select = $("session-select");
  if (!session || [...select.options].some((o) => o.value === session.id)) return;
  select.add(sessionOption(openSummary()), [...select.options].find((o) => o.value === MORE_SESSIONS) ?? null);
}

/** "paws · cat → lion · 3 curves · by alice · 2026-11-27 14:05" (the last change; "yours" for the user's own). */
function sessionLabel(summary) {
  const source = summary.source_name ?? state.shapeNames.get(summary.source) ?? summary.source;
  const target = summary.target_name ?? state.shapeNames.get(summary.target) ?? summary.target;
  const owner = summary.owner === state.user?.name ? "yours" : `by ${summary.owner || "nobody"}`;
  return [
    summary.name || summary.id,
    `${source} → ${target}`,
    `${summary.n_curves} curves`,
    owner,
    changedAt(summary.updated_at),
  ].join(" · ");
}

/** UNIX seconds as local "YYYY-MM-DD HH:MM". */
function changedAt(seconds) {
  const date = new Date(seconds * 1000);
  const two = (n) => String(n).padStart(2, "0");
  return `${date.getFullYear()}-${two(date.getMonth() + 1)}-${two(date.getDate())} ${two(date.getHours())}:${two(date.getMinutes())}`;
}

function sessionOption(summary) {
  const label = sessionLabel(summary);
  return Object.assign(new Option(label, summary.id), { title: label });
}

/** The open session's entry in the session list follows its curves and name. */
export function showSessionEntry() {
  const { session } = state;
  const option = [...$("session-select").options].find((o) => o.value === session?.id);
  if (option) option.textContent = option.title = sessionLabel(openSummary());
}

/** The open session as a list entry. */
function openSummary() {
  const { session } = state;
  return { ...session, n_curves: session.curves.length };
}

/** The open session's name, and the Rename and Delete buttons as the user may use them. */
export function showSessionName() {
  const input = $("session-name");
  input.value = state.session?.name ?? "";
  input.disabled = !mayEdit();
  $("rename-session").disabled = !mayEdit();
  $("delete-session").disabled = !mayManage();
}

/** The open session in the lists and the title. */
export function showSessionTitle() {
  const { session } = state;
  const [source, target] = [state.shapes.source.info, state.shapes.target.info];
  listOpenSession();
  $("session-select").value = session.id;
  $("source-select").value = session.source;
  $("target-select").value = session.target;
  const readOnly = mayEdit() ? "" : ` · read-only (shared by ${session.owner})`;
  document.body.classList.toggle("read-only", !mayEdit()); // the shapes take no curve clicks (see pickVertex)
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
