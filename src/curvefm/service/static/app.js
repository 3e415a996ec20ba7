// The curvefm web UI: the interactive loop of curve-constrained functional maps. Click corresponding curves on
// the source and the target; after every edit the target shows a source function carried by the map.
//
// The entry point: it binds every control of the page to what it does (controllers/), installs the hooks of the
// tests and benchmarks, and starts. The state lives in store.js; views/ draws it; api.js talks to the service.
import {
  addMembers,
  askAnnotation,
  assignEvenly,
  assignMember,
  chooseCollection,
  createCollection,
  grantRole,
  runReady,
  setTruth,
  showAgreementReport,
} from "./controllers/collections.js";
import { watchConnection } from "./controllers/connection.js";
import {
  acceptSuggestion,
  cancelPending,
  clickCurveList,
  pickVertex,
  pressKey,
  undo,
} from "./controllers/curves.js";
import {
  changeRegionRadius,
  followCameras,
  linkCameras,
  pickRegion,
  reorient,
  selectFunction,
  selectMap,
  showCurveTubes,
  useTextureImage,
} from "./controllers/display.js";
import { clickCommentList, toggleCommentMode } from "./controllers/comments.js";
import { clickMemberList, clickTemplateList, openNextMember, openWork, skip, step } from "./controllers/guide.js";
import "./controllers/live.js"; // follows the open session's changes made elsewhere (the store's "followed")
import { logOut, makeToken, watchLogin } from "./controllers/login.js";
import { openPair, upload } from "./controllers/pair.js";
import { cancelRefine, downloadLiveExport, refine } from "./controllers/refine.js";
import { toggleQuality } from "./controllers/quality.js";
import { toggleSuggestion } from "./controllers/suggestion.js";
import {
  chooseSession,
  deleteSession,
  renameSession,
  searchSessions,
  shareSession,
} from "./controllers/session.js";
import { start } from "./controllers/startup.js";
import { chooseTarget, setTexture, state } from "./store.js";
import { checkerboardTexture } from "./views/colors.js";
import { $ } from "./views/dom.js";
import { showParameters } from "./views/forms.js";
import { hideNewToken } from "./views/login.js";
import { showRadius } from "./views/page.js";
import { SIDES, viewports } from "./views/viewports.js";

setTexture(checkerboardTexture());
followCameras();
installTestHooks();
bindControls();
watchConnection();
watchLogin();
start();

function bindControls() {
  const on = (id, type, listener) => $(id).addEventListener(type, listener);
  const each = (selector, type, listener) => {
    for (const input of document.querySelectorAll(selector)) input.addEventListener(type, listener);
  };
  // the shapes, and clicks on them
  for (const side of SIDES) viewports[side].onPick((vertex, event) => pickVertex(side, vertex, event));
  window.addEventListener("keydown", pressKey);
  on("logout-button", "click", logOut);
  on("new-token-button", "click", makeToken);
  on("token-done", "click", hideNewToken);
  // Shapes & session
  on("open-pair", "click", openPair);
  on("upload-input", "change", (event) => upload(event.target));
  on("target-select", "change", chooseTarget);
  on("session-select", "change", (event) => chooseSession(event.target.value));
  on("sharing-select", "change", (event) => shareSession(event.target.value));
  on("session-search", "input", (event) => searchSessions(event.target.value));
  on("rename-session", "click", renameSession);
  on("session-name", "keydown", (event) => event.key === "Enter" && renameSession());
  on("delete-session", "click", deleteSession);
  // Collections
  on("collection-select", "change", (event) => chooseCollection(event.target.value));
  on("create-collection", "click", createCollection);
  on("add-members", "click", addMembers);
  on("member-list", "click", clickMemberList);
  on("grant-role-button", "click", grantRole);
  on("assign-evenly", "click", assignEvenly);
  on("assign-member-button", "click", assignMember);
  on("ask-annotation", "click", askAnnotation);
  on("truth-input", "change", (event) => setTruth(event.target));
  on("show-agreement", "click", showAgreementReport);
  on("my-work", "click", (event) => event.target.closest("li") && openWork(event.target.closest("li")));
  on("template-curves", "click", clickTemplateList);
  on("guide-skip", "click", skip);
  on("guide-previous", "click", () => step(-1));
  on("guide-next", "click", () => step(1));
  on("guide-next-member", "click", openNextMember);
  on("comment-list", "click", clickCommentList);
  on("comment-mode", "change", (event) => toggleCommentMode(event.target.checked));
  on("run-converter-select", "change", () => showParameters("converter", "run-converter"));
  on("run-all", "click", runReady);
  // Curves
  on("tracer-select", "change", () => showParameters("tracer"));
  on("curve-list", "click", clickCurveList);
  on("undo-button", "click", (event) => undo(event.timeStamp));
  on("cancel-pending", "click", cancelPending);
  // View
  each('input[name="function"]', "change", (event) => selectFunction(event.target.value));
  each('input[name="map"]', "change", (event) => selectMap(event.target.value, event.timeStamp));
  on("region-radius", "change", (event) => changeRegionRadius(event.timeStamp));
  on("region-radius", "input", (event) => showRadius(event.target.value));
  on("region-pick", "click", pickRegion);
  on("up-select", "change", reorient);
  on("reset-view", "click", reorient);
  on("link-cameras", "change", (event) => linkCameras(event.target.checked));
  on("show-curves", "change", (event) => showCurveTubes(event.target.checked));
  on("show-quality", "change", (event) => toggleQuality(event.target.checked));
  on("show-suggestion", "change", (event) => toggleSuggestion(event.target.checked));
  on("accept-suggestion", "click", (event) => acceptSuggestion(event.timeStamp));
  on("texture-input", "change", (event) => useTextureImage(event.target));
  // Refine & export
  on("converter-select", "change", () => showParameters("converter"));
  on("refine-button", "click", refine);
  on("cancel-refine", "click", cancelRefine);
  each(".live-export", "click", downloadLiveExport);
}

/** Hooks for tests and benchmarks: ids are file ids, positions client pixels. */
function installTestHooks() {
  window.curvefmStats = state.stats;
  window.curvefm = {
    get sessionId() {
      return state.session?.id ?? null;
    },
    get ready() {
      return state.ready;
    },
    /** The guided member and its current template curve: { collection, member, current } or null. */
    get guide() {
      return state.guide && { ...state.guide };
    },
    vertexToScreen(side, fileId) {
      const { mesh } = state.shapes[side];
      return viewports[side].vertexToScreen(mesh.fileToInternal[fileId]);
    },
    get quality() {
      const { quality } = state;
      return quality && { score: quality.score, revision: quality.revision, priorPending: quality.priorPending };
    },
    /** The suggested next curve as shown (ends possibly moved): { revision, source, target } in file ids, or null. */
    get suggestion() {
      const { suggestion } = state;
      return suggestion && { revision: suggestion.revision, source: [...suggestion.source], target: [...suggestion.target] };
    },
    /** The suggested curve's dashed line on one side as drawn: { points: how many, ends: the file ids of the drawn
     * vertices nearest its first and last points }, or null when none is drawn. */
    suggestionLine(side) {
      const line = viewports[side].suggestedLine;
      if (!line) return null;
      const { vertices, fileIds, nVertices } = state.shapes[side].mesh;
      const drawn = line.geometry.attributes.position;
      const nearest = (i) => {
        const at = [drawn.getX(i), drawn.getY(i), drawn.getZ(i)];
        let best = 0;
        let bestDistance = Infinity;
        for (let v = 0; v < nVertices; v++) {
          const distance = Math.hypot(...at.map((x, k) => x - vertices[3 * v + k]));
          if (distance < bestDistance) [best, bestDistance] = [v, distance];
        }
        return fileIds[best];
      };
      return { points: drawn.count, ends: [nearest(0), nearest(drawn.count - 1)] };
    },
    /** How many curve tubes one side draws. */
    tubeCount(side) {
      return viewports[side].curveTubes.size;
    },
    /** The file id of the (drawn) vertex ringed on one side as the weakest region, or null. */
    highlighted(side) {
      const vertex = viewports[side].highlightedVertex;
      return vertex >= 0 ? state.shapes[side].mesh.fileIds[vertex] : null;
    },
    /** The open member's review comments: [{ id, side, vertex (file id), text, author, reply_to, resolved }], or
     * null when the open session is no collection member's. */
    get comments() {
      const items = state.comments?.items;
      return items ? items.map((c) => ({ ...c, resolved: Boolean(c.resolved_by) })) : null;
    },
    get selectedComment() {
      return state.selectedComment;
    },
    /** The comment markers one side draws: [{ id, vertex (file id of the drawn vertex), selected }]. */
    commentMarkers(side) {
      const { fileIds } = state.shapes[side].mesh;
      return viewports[side].commentMarkers.map((m) => ({ id: m.id, vertex: fileIds[m.vertex], selected: m.selected }));
    },
    screenToVertex(side, x, y) {
      const vertex = viewports[side].pick(x, y);
      return vertex < 0 ? null : state.shapes[side].mesh.fileIds[vertex];
    },
  };
}
