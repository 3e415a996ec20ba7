// What happens when the service cannot be reached (a banner, and a health check every 2 s) and when it answers
// again (the lists and the session are brought in line with the service).
import { api, sleep } from "../api.js";
import { sessionReloaded, state, subscribe } from "../store.js";
import { showCurves } from "../views/curves.js";
import { banner, report, toast } from "../views/messages.js";
import { showSessionName, showSessionTitle, showSharing, showStatus } from "../views/page.js";
import { showFeedback } from "./feedback.js";
import { refreshQuality, refreshSolve } from "./quality.js";
import { refreshSuggestion } from "./suggestion.js";
import { refreshLists } from "./session.js";

/** Follow state.connected, which every request sets. */
export function watchConnection() {
  subscribe("connected", connectionChanged);
}

function connectionChanged(connected) {
  if (connected) {
    banner(null);
    toast("Connected to the service again.");
    resync();
    return;
  }
  banner("The service cannot be reached; retrying every 2 s. Edits made meanwhile are not saved.");
  pollHealth();
}

async function pollHealth() {
  while (!state.connected) {
    await sleep(2000);
    try {
      await api.health();
    } catch {
      // still unreachable: the banner stays
    }
  }
}

/** Bring the local state in line with the service (after a reconnect, a refused edit, or a change made elsewhere),
 * saying so when the session had changed. */
export async function resync() {
  try {
    await refreshLists();
    if (!state.session) return;
    const shown = state.session.revision;
    const record = await api.session(state.session.id);
    if (record.revision !== state.session.revision) {
      sessionReloaded(record);
      showCurves();
      showSessionTitle();
      showSessionName();
      showSharing();
      const curves = `${record.curves.length} curve${record.curves.length === 1 ? "" : "s"}`;
      toast(`The session changed elsewhere (revision ${shown} → ${record.revision}, ${curves}): shown as it is now.`);
      await showFeedback();
      await Promise.all([refreshSolve(), refreshQuality(), refreshSuggestion()]);
    }
    showStatus();
  } catch (error) {
    report(error, "The session could not be refreshed");
  }
}
