// What the Refine & export panel does: refine the live map into a pointwise one (a job whose files are offered
// for download and whose map the target can then be shown through), cancel it, download the live map and exports.
import { api, waitForJob } from "../api.js";
import { mapImages } from "../mesh.js";
import { setMap, setPointwise, setRefineJob, state } from "../store.js";
import { $ } from "../views/dom.js";
import { listJobFiles, saveUrl } from "../views/downloads.js";
import { ProgressRow, report } from "../views/messages.js";
import { pluginChoice } from "../views/forms.js";
import { enableRefine, showMapChoice, showRefineJob } from "../views/page.js";
import { showFeedback } from "./feedback.js";

export async function refine() {
  const { name: converter, params } = pluginChoice("converter");
  const row = new ProgressRow($("refine-progress"), `${converter} (revision ${state.session.revision})`);
  enableRefine(false);
  try {
    const job = await api.refine(state.session.id, converter, params);
    row.element.dataset.job = job.id; // its "refined" event adds no second row
    setRefineJob(job.id);
    showRefineJob();
    const done = await waitForJob(job.id, (update) => row.update(update));
    row.finish(`finished in ${(done.ended_at - done.started_at).toFixed(1)} s${guardVerdict(done.result)}`);
    await showRefinement(done);
    setMap("pointwise");
    showMapChoice();
    showFeedback();
  } catch (error) {
    row.finish(`failed: ${error.message}`, false);
    report(error, "The refinement did not finish");
  } finally {
    setRefineJob(null);
    showRefineJob();
    enableRefine(Boolean(state.session?.curves.length));
  }
}

/** What the guard did when it did not return the whole refinement (it made an intrinsic figure worse). */
function guardVerdict(result) {
  return result.kept === "initial" || result.kept === "stopped" ? `: ${result.reason}` : "";
}

/** A finished refinement's downloads and pointwise map (marked stale once the session's revision passed it). */
async function showRefinement(job) {
  listJobFiles($("downloads"), job.links);
  const text = await api.text(job.links["map_target_to_source.txt"]);
  const images = mapImages(text, state.shapes.target.mesh);
  const { points } = state.shapes.source; // a source drawn coarse shows each image at its nearest drawn vertex
  await points.load(images);
  setPointwise({ p2p: points.rows(images), revision: job.result.revision, converter: job.result.converter });
  showMapChoice();
}

/** The session's newest finished refinement, as it was left (the page was reloaded or the session reopened, or
 * another page's refinement finished); shown once. */
export async function restoreRefinement() {
  const session = state.session;
  try {
    const finished = (await api.refinements(session.id)).filter((job) => job.state === "finished");
    const newest = finished.at(-1);
    const rows = $("refine-progress");
    if (!newest || state.session !== session || rows.querySelector(`[data-job="${newest.id}"]`)) return;
    const row = new ProgressRow(rows, `${newest.result.converter} (revision ${newest.result.revision})`);
    row.element.dataset.job = newest.id;
    row.finish(`finished ${new Date(newest.ended_at * 1000).toLocaleString()}`);
    await showRefinement(newest);
  } catch (error) {
    report(error, "The session's refinements could not be listed");
  }
}

export async function cancelRefine() {
  try {
    if (state.refineJob) await api.cancelJob(state.refineJob);
  } catch (error) {
    report(error, "The refinement could not be canceled");
  }
}

/** A live export the service makes (C as .npy, the maps as .mat, the textured target as .zip, landmark files), named by the link's
 * data-export; the server names the file after the session, "live" and the revision. */
export function downloadLiveExport(event) {
  event.preventDefault();
  if (!state.session) return;
  saveUrl(`/sessions/${encodeURIComponent(state.session.id)}/exports/${event.currentTarget.dataset.export}`);
}
