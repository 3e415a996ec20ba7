// Opening a session: its record and both shapes are loaded, then shown with the carried function drawn; and
// sharing it with the lab.
import { api } from "../api.js";
import { diagonal, xyzValues } from "../functions.js";
import { decodeMesh } from "../mesh.js";
import { VertexPoints } from "../points.js";
import { sessionOpened, sessionShared, setReady, setShapeNames, state } from "../store.js";
import { showCollection, showMemberChoices } from "../views/collections.js";
import { placeCurves, showCurves, showPending } from "../views/curves.js";
import { $ } from "../views/dom.js";
import { listJobFiles } from "../views/downloads.js";
import { report, toast } from "../views/messages.js";
import {
  openPairPanel,
  showLists,
  showLoading,
  showMapChoice,
  showSessionTitle,
  showSharing,
  showStatus,
} from "../views/page.js";
import { orientViews, paint, showShapes, showSource, SIDES, viewports } from "../views/viewports.js";
import { carriedRows } from "./feedback.js";
import { refreshQuality } from "./quality.js";
import { restoreRefinement } from "./refine.js";

/** The session list's choice. */
export function chooseSession(id) {
  if (id) openSession(id);
}

/** Load the session (its id goes into the page's URL, and a guided member's collection and id) and show it;
 * state.ready once its first texture is drawn. guide: see state.guide. */
export async function openSession(id, { guide = null } = {}) {
  const url = new URL(window.location.href);
  url.searchParams.set("session", id);
  for (const key of ["collection", "member"]) {
    if (guide) url.searchParams.set(key, guide[key]);
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
    showSharing();
    showStatus();
    showCollection();
    refreshQuality();
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

/** Fetch the shapes and sessions and show them in the lists; resolves to { shapes, sessions }. */
export async function refreshLists() {
  const [shapes, sessions] = await Promise.all([api.shapes(), api.sessions()]);
  setShapeNames(shapes);
  showLists(shapes, sessions);
  showMemberChoices(shapes);
  return { shapes, sessions };
}
