// What happens when the service cannot be reached (a banner, and a health check every 2 s) and when it answers
// again (the lists and the session are brought in line with the service).
import { api, sleep } from "../api.js";
import { sessionReloaded, state, subscribe } from "../store.js";
import { showCurves } from "../views/curves.js";
import { banner, report, toast } from "../views/messages.js";
import { showStatus } from "../views/page.js";
import { showFeedback } from "./feedback.js";
import { refreshQuality } from "./quality.js";
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

/** Bring the local state in line with the service (after a reconnect or a refused edit). */
export async function resync() {
  try {
    await refreshLists();
    if (!state.session) return;
    const record = await api.session(state.session.id);
    if (record.revision !== state.session.revision) {
      sessionReloaded(record);
      showCurves();
      await showFeedback();
      await refreshQuality();
    }
    showStatus();
  } catch (error) {
    report(error, "The session could not be refreshed");
  }
}
