// Guided clicking on a collection's member: its session opens in the two viewports (the template as source, the
// member as target) and the page walks through the template curves: the current one is drawn thicker and named in
// the prompt, the person clicks its start and end (Shift+click: waypoints) on the target only, and the answer
// updates the map and the texture as any curve edit does; then the next unanswered template curve is current.
import { answerOf, clearPending, recordEdit, setCurrentTemplateCurve, state, templateCurves } from "../store.js";
import { nextMember, openCollectionsPanel, showCollection } from "../views/collections.js";
import { showCurves, showPending, showTracing } from "../views/curves.js";
import { tracerChoice } from "../views/forms.js";
import { chooseCollection, removeMember, reviewMember, submitMember } from "./collections.js";
import { openSession } from "./session.js";
import { edits, runEdit } from "./edits.js";

const MEMBER_ACTIONS = {
  open: (memberId) => openMember(memberId),
  remove: removeMember,
  submit: submitMember,
  accept: (memberId) => reviewMember(memberId, "accept"),
  "request-changes": (memberId) => reviewMember(memberId, "request_changes"),
};

/** A click in the member list: Open opens the member for guided clicking, Remove removes it, Submit / Accept /
 * Request changes move it through review. */
export function clickMemberList(event) {
  const button = event.target.closest("button[data-action]");
  if (!button) return;
  MEMBER_ACTIONS[button.dataset.action](button.closest("li[data-member-id]").dataset.memberId);
}

/** "Next member": open the next member whose template curves are not all answered (see nextMember). */
export function openNextMember() {
  const next = nextMember();
  if (next) return openMember(next);
}

/** Open a member's session (``further``: { session, annotator } of a further annotation of it instead) with the
 * first unanswered template curve current. */
export async function openMember(memberId, further = null) {
  const { collection, members } = state.collection;
  const session = further?.session ?? members.find((m) => m.id === memberId).session;
  const guide = { collection: collection.id, member: memberId, current: null, annotator: further?.annotator ?? null };
  await openSession(session, { guide });
  if (state.guide !== guide) return; // the session did not open, or another one was opened meanwhile
  setCurrentTemplateCurve(templateCurves().find((curve) => !curve.answer)?.id ?? null);
  openCollectionsPanel();
  showCollection();
  redraw();
}

/** A "My work" entry: open its collection, and a further annotation's own session, guided. */
export async function openWork(entry) {
  const { collection, member, session, further } = entry.dataset;
  await chooseCollection(collection);
  if (further !== "true" || state.collection?.collection.id !== collection) return;
  await openMember(member, { session, annotator: state.user.name });
}

/** The target side of the current template curve is closed: answer it, then move on to the next unanswered one. */
export function answerTemplateCurve(clickTime) {
  const templateCurve = state.guide.current;
  const { fileIds } = state.shapes.target.mesh;
  const target = state.pending.points.target.map((vertex) => fileIds[vertex]);
  clearPending();
  showTracing();
  return runEdit(clickTime, "answer", `${templateCurve} was not answered`, async () => {
    const previous = answerOf(templateCurve);
    const edit = await edits.answer({ template_curve: templateCurve, target, ...tracerChoice() });
    recordEdit(previous ? "replace" : "add", previous ?? edit.curve);
    if (state.guide?.current === templateCurve) setCurrentTemplateCurve(following(1, (curve) => !curve.answer));
    return edit;
  });
}

/** "Skip": the next template curve not answered yet becomes current (none: no curve is current). */
export function skip() {
  moveTo(following(1, (curve) => !curve.answer));
}

/** "Next" / "Previous": the template curve after / before the current one, answered or not (answering again
 * replaces the answer). */
export function step(direction) {
  moveTo(following(direction, () => true) ?? state.guide.current);
}

/** A click in the template curve list makes that curve current. */
export function clickTemplateList(event) {
  const item = event.target.closest("li[data-template-curve]");
  if (item) moveTo(item.dataset.templateCurve);
}

function moveTo(curveId) {
  if (!state.guide) return;
  clearPending();
  setCurrentTemplateCurve(curveId);
  redraw();
}

function redraw() {
  showCurves();
  showPending();
}

/** The template curve ``direction`` (1 or -1) places on from the current one, wrapping, for which accept(curve)
 * holds; the current one itself only when no curve is current. Null when none does. */
function following(direction, accept) {
  const curves = templateCurves();
  const count = curves.length;
  let at = curves.findIndex((curve) => curve.id === state.guide.current);
  if (at < 0) at = direction > 0 ? -1 : count;
  for (let i = 1; i <= count; i++) {
    const curve = curves[(((at + direction * i) % count) + count) % count];
    if (curve.id !== state.guide.current && accept(curve)) return curve.id;
  }
  return null;
}
