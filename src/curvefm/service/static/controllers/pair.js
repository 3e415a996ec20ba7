// What the Shapes & session panel does: upload a mesh, and open a new session on a pair of shapes (computing
// their bases first when they are missing).
import { api, waitForJob } from "../api.js";
import { chooseTarget, setPairInProgress } from "../store.js";
import { $ } from "../views/dom.js";
import { ProgressRow, report, toast } from "../views/messages.js";
import { showPairInProgress } from "../views/page.js";
import { openSession, refreshLists } from "./session.js";

/** Open a new session on the chosen pair: request missing bases, show their jobs, then create it. */
export async function openPair() {
  const source = $("source-select").value;
  const target = $("target-select").value;
  const k = Number($("k-input").value);
  if (!source || !target) return toast("Upload or pick two shapes first.", "error");
  const box = $("pair-progress");
  box.replaceChildren();
  setPairInProgress(true);
  showPairInProgress();
  try {
    await Promise.all([...new Set([source, target])].map((id) => ensureBasis(id, k, box)));
    const session = await api.createSession({ source, target, k, name: $("pair-name").value.trim() });
    $("pair-name").value = "";
    await refreshLists();
    await openSession(session.id);
  } catch (error) {
    report(error, "The pair could not be opened");
  } finally {
    setPairInProgress(false);
    showPairInProgress();
  }
}

/** Request the basis (a job that finishes at once when it exists, and is shared while it runs) and show it. */
async function ensureBasis(shapeId, k, box) {
  const info = await api.shape(shapeId);
  const row = new ProgressRow(box, `basis of ${info.name}`);
  const job = await api.requestBasis(shapeId, k);
  try {
    await waitForJob(job.id, (update) => row.update(update));
    row.finish(`k=${k} ready`);
  } catch (error) {
    row.finish(`failed: ${error.message}`, false);
    throw error;
  }
}

/** Upload the file of a file input; the new shape becomes the chosen target (and the previous target the
 * source: two uploads make a pair). */
export async function upload(input) {
  const [file] = input.files;
  if (!file) return;
  const row = new ProgressRow($("pair-progress"), `upload ${file.name}`);
  try {
    const shape = await api.uploadShape(file);
    row.finish(`${shape.name}: ${shape.n_vertices} vertices`);
    const previous = $("target-select").value;
    await refreshLists();
    if (previous && previous !== shape.id) $("source-select").value = previous;
    $("target-select").value = shape.id;
    chooseTarget();
    const warnings = shape.report.warnings ?? [];
    toast(`Uploaded ${shape.name}${warnings.length ? ` (${warnings.join("; ")})` : ""}. Pick the pair and open it.`);
  } catch (error) {
    row.finish(`rejected: ${error.message}`, false);
    report(error, `The upload of ${file.name} was rejected`);
  } finally {
    input.value = "";
  }
}
