// The page's start: the login, the plugins, the lists, then the session named in the URL, else the newest one,
// else wait for one (the demo's, still computing its bases) unless the user opens a pair of their own first.
import { api, sleep } from "../api.js";
import { setPlugins, state } from "../store.js";
import { showPlugins } from "../views/forms.js";
import { report } from "../views/messages.js";
import { openPairPanel, showLoading } from "../views/page.js";
import { openCollection, refreshCollections } from "./collections.js";
import { openMember } from "./guide.js";
import { logIn } from "./login.js";
import { openSession, refreshLists } from "./session.js";

export async function start() {
  if (!(await logIn())) {
    showLoading("Not logged in: open the login URL that `curvefm serve` printed.");
    return;
  }
  try {
    setPlugins(await api.plugins());
    showPlugins("tracer");
    showPlugins("converter");
    showPlugins("converter", "run-converter");
    const [{ sessions }] = await Promise.all([refreshLists(), refreshCollections()]);
    const query = new URLSearchParams(window.location.search);
    if (await openGuidedMember(query)) return;
    const id = query.get("session") ?? sessions[0]?.id;
    if (id) await openSession(id);
    else await waitForFirstSession();
  } catch (error) {
    report(error, "The UI could not start");
    showLoading(`The UI could not start: ${error.message}`);
  }
}

/** The member named in the page's URL, guided (the page was reloaded; with an annotator: their further annotation,
 * the session named); resolves to whether it opened. */
async function openGuidedMember(query) {
  const [collection, member, annotator] = ["collection", "member", "annotator"].map((key) => query.get(key));
  if (!collection) return false;
  try {
    await openCollection(collection);
  } catch (error) {
    report(error, `Collection ${collection} could not be opened`);
    return false;
  }
  if (!member || !state.collection.members.some((m) => m.id === member)) return false;
  await openMember(member, annotator ? { session: query.get("session"), annotator } : null);
  return true;
}

/** No session yet: poll until one appears, unless the user starts a pair of their own meanwhile (or logs out). The
 * shape lists are rebuilt only when the service's shapes or sessions changed. */
async function waitForFirstSession() {
  openPairPanel();
  showLoading(
    "No session yet. Pick two shapes (or upload them) and open the pair; " +
      "the demo of `curvefm serve --demo` opens by itself once it is ready.",
  );
  let known = "";
  while (!state.session && !state.pairInProgress && !state.loggedOut) {
    await sleep(1500);
    try {
      const [shapes, { items: sessions }] = await Promise.all([api.shapes(), api.sessionPage(1)]);
      const now = [...shapes, ...sessions].map((item) => item.id).join();
      if (now !== known) await refreshLists();
      known = now;
      if (sessions.length && !state.session && !state.pairInProgress) await openSession(sessions[0].id);
    } catch (error) {
      if (error.kind !== "network" && !state.loggedOut) throw error;
    }
  }
}
