// Live sessions: the open session's changes made elsewhere (another page, another user, another API process)
// arrive as Server-Sent Events (GET /sessions/{id}/events); the page reloads what changed and redraws, and shows
// who else has the session open. An event is a hint (its kind and the session's revision), never the data.
import { api } from "../api.js";
import { setViewers, state, subscribe } from "../store.js";
import { toast } from "../views/messages.js";
import { showViewers } from "../views/presence.js";
import { refreshComments } from "./comments.js";
import { resync } from "./connection.js";
import { priorLanded } from "./feedback.js";
import { refreshQuality } from "./quality.js";
import { restoreRefinement } from "./refine.js";
import { leaveDeletedSession } from "./session.js";

let events = null; // the EventSource of the open session
let announced = -1; // the newest revision the service announced for it
let syncing = null; // the resync under way, if any
let again = false; // another announcement came while it ran

/** Follow the open session's changes (once it is shown); the one followed before is left. */
function followSession(sessionId) {
  events?.close();
  announced = -1;
  setViewers([]);
  showViewers();
  events = new EventSource(api.eventsUrl(sessionId));
  events.onmessage = (message) => {
    if (state.session?.id === sessionId) received(JSON.parse(message.data));
  };
  // a dropped connection is reopened by the browser (its hello compares revisions); a refusal (429, 404) is final
  events.onerror = () => {
    if (events?.readyState !== EventSource.CLOSED) return;
    const why = "too many of your pages do, or the session is gone";
    toast(`This page does not follow the changes made elsewhere to the session (${why}).`);
  };
}

/** Stop following the open session (it is gone, no longer readable, or being deleted by this page). */
function stopFollowing() {
  events?.close();
  events = null;
  setViewers([]);
  showViewers();
}

function received(event) {
  switch (event.kind) {
    case "hello": // also after a reconnect: what changed meanwhile is read again (comments have no revision)
      showPresence(event.viewers);
      announce(event.revision);
      refreshComments();
      break;
    case "viewers":
      showPresence(event.viewers);
      break;
    case "prior": // the map of this revision improved: the texture, the quality and the suggestion follow
      if (event.revision === state.session.revision && state.editing === 0) refreshQuality();
      priorLanded(event.revision);
      break;
    case "comments": // the member's review comments changed (here, elsewhere, on another API process)
      refreshComments();
      break;
    case "refined":
      if (!state.refineJob) restoreRefinement(); // another page's refinement; this page follows its own
      break;
    case "deleted":
      stopFollowing();
      toast(`Session ${state.session.name || state.session.id} was deleted (by its owner or an admin).`, "error");
      leaveDeletedSession();
      break;
    case "forbidden":
      stopFollowing();
      toast("The session's owner no longer shares it with you: its changes are not shown any more.", "error");
      break;
    case "logged-out":
      stopFollowing();
      toast("Your login has ended (a logout, or your token was changed): log in again to follow the session.", "error");
      break;
    case "reconnected": // events may have been lost meanwhile
      catchUp(true);
      refreshComments();
      break;
    case "closing": // the server stops: the browser reconnects on its own
      break;
    default:
      if (typeof event.revision === "number") announce(event.revision);
  }
}

function showPresence(viewers) {
  setViewers(viewers);
  showViewers();
}

/** The session is at ``revision`` now: reload it if the page shows an older one. */
function announce(revision) {
  announced = Math.max(announced, revision);
  catchUp();
}

/** Once no edit of this page is under way (its answer brings the revision it made), bring the page up to the
 * newest announced revision, one resync at a time. */
function catchUp(always = false) {
  if (state.editing > 0 || !state.session) return;
  if (!always && announced <= state.session.revision) return;
  if (syncing) {
    again = true;
    return;
  }
  syncing = resync().finally(() => {
    syncing = null;
    if (again) {
      again = false;
      catchUp();
    }
  });
}

subscribe("editing", () => catchUp());
subscribe("followed", (sessionId) => (sessionId ? followSession(sessionId) : stopFollowing()));
