// Opening a session: its record and both shapes are loaded, then shown with the carried function drawn; and
// sharing it with the lab.
import { api } from "../api.js";
import { diagonal, xyzValues } from "../functions.js";
import { decodeMesh } from "../mesh.js";
import { VertexPoints } from "../points.js";
import {
  sessionOpened,
  sessionRenamed,
  sessionShared,
  setFollowed,
  setReady,
  setShapeNames,
  state,
} from "../store.js";
import { showCollection, showMemberChoices } from "../views/collections.js";
import { placeCurves, showCurves, showPending } from "../views/curves.js";
import { $ } from "../views/dom.js";
import { listJobFiles } from "../views/downloads.js";
import { report, toast } from "../views/messages.js";
import {
  MORE_SESSIONS,
  openPairPanel,
  showLists,
  showLoading,
  showMapChoice,
  showSessionName,
  showSessionTitle,
  showSharing,
  showStatus,
} from "../views/page.js";
import { orientViews, paint, showShapes, showSource, SIDES, viewports } from "../views/viewports.js";
import { refreshComments } from "./comments.js";
import { carriedRows } from "./feedback.js";
import { refreshQuality, refreshSolve } from "./quality.js";
import { refreshSuggestion } from "./suggestion.js";
import { restoreRefinement } from "./refine.js";

/** The session list's choice. */
export function chooseSession(id) {
  if (id === MORE_SESSIONS) showMoreSessions();
  else if (id) openSession(id);
}

/** The session list shows the newest SESSION_PAGE sessions (of their own: a collection's members are listed under
 * it), those whose name or shape names contain the search text, and a page more each time its "more" entry is
 * chosen. */
const SESSION_PAGE = 50;
const MAX_PAGE = 500;
const SEARCH_DELAY_MS = 250;
let sessionsShown = SESSION_PAGE;
let sessionQuery = "";
let searchTimer = null;

/** Typing in the search box lists the sessions that match, once the typing pauses. */
export function searchSessions(text) {
  clearTimeout(searchTimer);
  searchTimer = setTimeout(async () => {
    sessionQuery = text.trim();
    sessionsShown = SESSION_PAGE;
    try {
      await refreshLists();
    } catch (error) {
      report(error, "The sessions could not be searched");
    }
  }, SEARCH_DELAY_MS);
}

async function showMoreSessions() {
  sessionsShown = Math.min(sessionsShown + SESSION_PAGE, MAX_PAGE);
  try {
    await refreshLists();
  } catch (error) {
    report(error, "More sessions could not be listed");
  }
}

/** Load the session (its id goes into the page's URL, and a guided member's collection and id) and show it;
 * state.ready once its first texture is drawn. guide: see state.guide. */
export async function openSession(id, { guide = null } = {}) {
  const url = new URL(window.location.href);
  url.searchParams.set("session", id);
  for (const key of ["collection", "member", "annotator"]) {
    if (guide?.[key]) url.searchParams.set(key, guide[key]);
    else url.searchParams.delete(key);
  }
  window.history.replaceState(null, "", url);
  setReady(false);
  showLoading("Loading the session…");
  try {
    const session = await api.session(id);
    const [source, target] = await Promise.all(SIDES.map((side) => loadShape(session[side], side === "source")));
    sessionOpened(session, { source, target }, guide);
    await placeCurves();
    listJobFiles($("downloads"), {});
    $("refine-progress").replaceChildren();
    showMapChoice();
    showShapes();
    orientViews();
    showCurves();
    showPending();
    showSource();
    paint("target", state.fn, await carriedRows());
    for (const side of SIDES) viewports[side].warmUp();
    await viewports.target.drawn();
    showLoading(null);
    setReady(true);
    showSessionTitle();
    showSessionName();
    showSharing();
    showStatus();
    showCollection();
    refreshComments();
    setFollowed(id);
    refreshSolve();
    refreshQuality();
    refreshSuggestion();
    restoreRefinement();
  } catch (error) {
    report(error, `Session ${id} could not be opened`);
    showLoading(`Session ${id} could not be opened: ${error.message}`);
    openPairPanel();
  }
}

async function loadShape(id, withFunctions) {
  const [info, payload] = await Promise.all([api.shape(id), api.mesh(id)]);
  const mesh = decodeMesh(payload.buffer);
  const shape = { info, mesh, points: new VertexPoints(id, mesh), diagonal: diagonal(mesh.vertices) };
  if (withFunctions) Object.assign(shape, { uv: mesh.texcoords, xyz: xyzValues(mesh.vertices) });
  return shape;
}

/** The sharing select's choice: private, read or edit (the owner's, or an admin's). */
export async function shareSession(sharing) {
  try {
    sessionShared(await api.shareSession(state.session.id, sharing));
    const now = sharing === "private" ? "private" : `shared: every user may ${sharing} it`;
    toast(`Session ${state.session.name || state.session.id} is now ${now}.`);
    await refreshLists();
  } catch (error) {
    report(error, "The sharing could not be changed");
  }
  showSharing();
  showStatus();
}

/** "Rename": the open session takes the name in the name box (the owner, an admin, or anyone it is shared editable
 * with). */
export async function renameSession() {
  const name = $("session-name").value.trim();
  if (!name) return toast("Give the session a name first.", "error");
  try {
    sessionRenamed(await api.renameSession(state.session.id, name));
    toast(`The session is now called ${name}.`);
    await refreshLists();
  } catch (error) {
    report(error, "The session could not be renamed");
  }
  showSessionTitle();
  showSessionName();
}

/** "Delete…": after the user confirms, delete the open session (and its refinement results), then open the newest
 * session left. */
export async function deleteSession() {
  const { session } = state;
  const what = `session "${session.name || session.id}" with its ${session.curves.length} curves and refinement results`;
  if (!window.confirm(`Delete ${what}? This cannot be undone.`)) return;
  setFollowed(null); // this page deletes it: its own event would tell it so a second time
  try {
    await api.deleteSession(session.id);
    toast(`Deleted ${what}.`);
    await leaveDeletedSession();
  } catch (error) {
    report(error, "The session could not be deleted");
    setFollowed(session.id);
  }
}

/** The open session was deleted: open the newest session listed, or start over without one. */
export async function leaveDeletedSession() {
  setReady(false);
  const gone = state.session.id;
  const { sessions } = await refreshLists();
  [...$("session-select").options].find((option) => option.value === gone)?.remove();
  const next = sessions.find((s) => s.id !== gone);
  if (next) await openSession(next.id);
  else window.location.replace(window.location.pathname);
}

/** Fetch the shapes and sessions and show them in the lists; resolves to { shapes, sessions }. */
export async function refreshLists() {
  const [shapes, page] = await Promise.all([api.shapes(), api.sessionPage(sessionsShown, sessionQuery)]);
  const sessions = page.items;
  setShapeNames(shapes);
  showLists(shapes, sessions, page.total - sessions.length);
  showMemberChoices(shapes);
  return { shapes, sessions };
}
