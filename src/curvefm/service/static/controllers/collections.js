// What the Collections panel does: list the collections, open one (its members' progress is polled while their
// bases compute), make the open session's curves a new collection's template, add members from the shape library,
// remove a member (after asking), assign members to annotators (by hand or evenly), ask for a further annotation
// of a member, give a member its ground truth (a check member), show the agreement between annotators, and run the ready members' refinements as one batch whose progress is polled until
// its archive can be downloaded.
import { api, sleep } from "../api.js";
import { setCollection, state } from "../store.js";
import {
  showAgreement,
  showCollection,
  showCollectionList,
  showMyWork,
  showRoles,
  showRunLinks,
} from "../views/collections.js";
import { showCurves, showPending } from "../views/curves.js";
import { $ } from "../views/dom.js";
import { pluginChoice } from "../views/forms.js";
import { ProgressRow, report, toast } from "../views/messages.js";
import { refreshComments } from "./comments.js";
import { leaveDeletedSession } from "./session.js";

const RUN_POLL_MS = 500;
const BASIS_POLL_MS = 1000;
const PENDING = ["queued", "started"];

export async function refreshCollections() {
  showCollectionList(await api.collections());
  showMyWork(await api.myWork());
}

/** "Grant": give the named user the chosen role in the open collection. */
export async function grantRole() {
  const id = state.collection.collection.id;
  const user = $("grant-user").value.trim();
  if (!user) return toast("Name the user to grant a role to.", "error");
  try {
    const granted = await api.grant(id, user, $("grant-role-select").value);
    toast(`${granted.user} is now ${granted.role} of this collection.`);
    $("grant-user").value = "";
    showRoles(await api.roles(id));
  } catch (error) {
    report(error, "The role could not be granted");
  }
}

/** "Assign evenly": give the members that have no annotator to the collection's annotators, the fewest first. */
export async function assignEvenly() {
  const id = state.collection.collection.id;
  try {
    const annotators = (await api.roles(id)).filter((r) => r.role === "annotator").map((r) => r.user);
    if (!annotators.length) return toast("Grant the annotator role to someone first.", "error");
    const unassigned = state.collection.members.filter((m) => !state.collection.assignees[m.id]).map((m) => m.id);
    if (!unassigned.length) return toast("Every member has an annotator already.");
    await api.assign(id, annotators, unassigned);
    toast(`${unassigned.length} member(s) spread among ${annotators.join(", ")}.`);
    await openCollection(id);
  } catch (error) {
    report(error, "The members could not be assigned");
  }
}

/** "Assign": give the chosen member to the chosen user ("no one": unassign it). */
export async function assignMember() {
  const id = state.collection.collection.id;
  const member = $("assign-member-select").value;
  const user = $("assign-user-select").value || null;
  if (!member) return toast("The collection has no member to assign.", "error");
  try {
    await api.assignMember(id, member, user);
    toast(user ? `Member ${member} assigned to ${user}.` : `Member ${member} assigned to no one.`);
    await refreshCollection();
    showMyWork(await api.myWork());
  } catch (error) {
    report(error, "The member could not be assigned");
  }
}

/** "Ask for another annotation": the chosen user annotates the chosen member once more, independently. */
export async function askAnnotation() {
  const id = state.collection.collection.id;
  const member = $("assign-member-select").value;
  const user = $("assign-user-select").value;
  if (!member || !user) return toast("Choose a member and the user to annotate it again.", "error");
  try {
    await api.addAnnotation(id, member, user);
    toast(`${user} now annotates member ${member} too, in a session of their own.`);
  } catch (error) {
    report(error, "The further annotation could not be asked for");
  }
}

/** "Ground truth…": the chosen file becomes the chosen member's ground truth (a check member, blind to annotators). */
export async function setTruth(input) {
  const id = state.collection.collection.id;
  const member = $("assign-member-select").value;
  const [file] = input.files;
  input.value = ""; // the same file chosen again is a new choice
  if (!member || !file) return toast("Choose a member, then its ground-truth file.", "error");
  try {
    const truth = await api.setTruth(id, member, file);
    toast(`Member ${member} is a check member now (${truth.known} of ${truth.rows} template vertices known).`);
  } catch (error) {
    report(error, "The ground truth was refused");
  }
}

/** "Agreement": how far apart the annotations of the members annotated twice or more are. */
export async function showAgreementReport() {
  try {
    showAgreement(await api.agreement(state.collection.collection.id));
  } catch (error) {
    report(error, "The agreement could not be computed");
  }
}

/** The collection select's choice ("" closes the panel's collection). */
export async function chooseCollection(id) {
  if (!id) {
    setCollection(null);
    showCollection();
    return;
  }
  try {
    await openCollection(id);
  } catch (error) {
    report(error, `Collection ${id} could not be opened`);
  }
}

/** Show the collection, follow its newest run, and poll its members while a basis is being computed. */
export async function openCollection(id) {
  const guided = state.guide;
  setCollection(await api.collection(id));
  if (guided && !state.guide) redrawCurves(); // the member shown belonged to another collection
  $("collection-select").value = id;
  $("run-progress").replaceChildren();
  showRunLinks(null);
  showAgreement(null);
  showCollection();
  showRoles(await api.roles(id));
  refreshComments();
  const newest = state.collection.collection.runs.at(-1);
  if (newest) followRun(id, await api.run(id, newest.id));
  watchBases(id);
}

/** Fetch the collection again and show its members' progress (after an edit, a run, a basis). */
export async function refreshCollection() {
  if (!state.collection) return;
  try {
    setCollection(await api.collection(state.collection.collection.id));
    showCollection();
  } catch (error) {
    report(error, "The collection's progress could not be refreshed");
  }
}

async function watchBases(id) {
  const computing = () => state.collection?.members.some((m) => PENDING.includes(m.basis));
  while (state.collection?.collection.id === id && computing()) {
    await sleep(BASIS_POLL_MS);
    if (state.collection?.collection.id === id) await refreshCollection();
  }
}

function redrawCurves() {
  if (!state.session) return;
  showCurves();
  showPending();
}

/** "Make template": a new collection whose template is the open session's source, whose template curves are its
 * curves' source sides, and whose first member is its target with its curves. */
export async function createCollection() {
  const { session } = state;
  const name = $("collection-name").value.trim();
  try {
    const view = await api.createCollection({ name, template: session.source, from_session: session.id });
    $("collection-name").value = "";
    toast(`Collection ${view.collection.name || view.collection.id}: ${view.collection.curves.length} template curves.`);
    await refreshCollections();
    await openCollection(view.collection.id);
  } catch (error) {
    report(error, "The collection could not be made");
  }
}

/** Add the shapes chosen in the member list (several at once); their bases are computed as jobs. */
export async function addMembers() {
  const shapes = [...$("member-shapes").selectedOptions].map((option) => option.value);
  if (!shapes.length) return toast("Choose one or more shapes to add (Ctrl+click or Shift+click).", "error");
  const id = state.collection.collection.id;
  try {
    setCollection(await api.addMembers(id, shapes));
    for (const option of $("member-shapes").options) option.selected = false;
    showCollection();
    await refreshCollections();
    watchBases(id);
  } catch (error) {
    report(error, "The members could not be added");
  }
}

/** "Run the members that are ready": refine the members that have curves with the chosen converter, one job each
 * on the workers (the others keep their previous run's jobs). */
export async function runReady() {
  const { name: converter, params } = pluginChoice("converter", "run-converter");
  const id = state.collection.collection.id;
  $("run-all").disabled = true;
  try {
    const run = await api.startRun(id, converter, params);
    const waiting = state.collection.members.length - run.members.filter((m) => !m.carried).length;
    if (waiting > 0) toast(`${waiting} member(s) without curves wait for a later run.`);
    await followRun(id, run);
  } catch (error) {
    report(error, "The batch run did not start");
  } finally {
    showCollection();
  }
}

/** A member's Remove button: after the user confirms, the member leaves the collection with its session, curves
 * and refinement results. */
export async function removeMember(memberId) {
  const view = state.collection;
  const member = view.members.find((m) => m.id === memberId);
  const what = `member ${member.shape_name} (${member.id}) of ${view.collection.name || view.collection.id}`;
  const question = `Remove ${what}? Its session, its ${member.curves_done + member.extra_curves} curves and its refinement results are deleted.`;
  if (!window.confirm(question)) return;
  try {
    await api.removeMember(view.collection.id, memberId);
    toast(`Removed ${what}.`);
    const wasOpen = state.session?.id === member.session;
    await refreshCollection();
    await refreshCollections();
    if (wasOpen) await leaveDeletedSession();
  } catch (error) {
    report(error, "The member could not be removed");
  }
}

/** A member's Submit button: submit it for review (its curves are locked until a reviewer decides). */
export async function submitMember(memberId) {
  try {
    await api.submitMember(state.collection.collection.id, memberId);
    toast(`Member ${memberId} submitted for review.`);
    await refreshCollection();
  } catch (error) {
    report(error, "The member could not be submitted");
  }
}

/** Accept / Request changes (asking for the comment the annotator will read). */
export async function reviewMember(memberId, decision) {
  const comment = decision === "request_changes" ? window.prompt(`What should change in ${memberId}?`) : "";
  if (comment === null) return;
  try {
    const review = await api.reviewMember(state.collection.collection.id, memberId, decision, comment);
    toast(`Member ${memberId}: ${review.state.replace("_", " ")}.`);
    await refreshCollection();
  } catch (error) {
    report(error, "The review could not be recorded");
  }
}

/** Show a run's progress per member until it ends (or another collection is chosen), then its archive. */
async function followRun(id, started) {
  const box = $("run-progress");
  box.replaceChildren();
  showRunLinks(null);
  const rows = new Map(started.members.map((m) => [m.member, new ProgressRow(box, `${m.member} · ${started.converter}`)]));
  let run = started;
  while (["queued", "running"].includes(run.state)) {
    for (const member of run.members) rows.get(member.member).update(member);
    await sleep(RUN_POLL_MS);
    if (state.collection?.collection.id !== id) return;
    run = await api.run(id, run.id);
  }
  for (const member of run.members) {
    const finished = member.state === "finished";
    rows.get(member.member).finish(finished ? "finished" : `${member.state}: ${member.error ?? member.message}`, finished);
  }
  if (run.state === "finished") {
    const kinds = ["npz", "zip"];
    showRunLinks(Object.fromEntries(kinds.map((kind) => [`archive.${kind}`, api.archiveUrl(id, run.id, kind)])));
  }
  await refreshCollection();
}
