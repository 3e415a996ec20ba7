// The Collections panel: the collections one may see, the chosen one's members with their progress, the guide
// through the template curves of the member being clicked, and the batch run's downloads.
import { state, templateCurves } from "../store.js";
import { $ } from "./dom.js";
import { curveColor, pendingHint } from "./hints.js";

/** The collection select (GET /collections): the user's own first, then those shared with them. */
export function showCollectionList(summaries) {
  const select = $("collection-select");
  const own = summaries.filter((c) => c.owner === state.user?.name);
  const shared = summaries.filter((c) => c.owner !== state.user?.name);
  const group = (label, items) => {
    const element = Object.assign(document.createElement("optgroup"), { label });
    element.append(...items.map((c) => new Option(collectionLabel(c), c.id)));
    return items.length ? [element] : [];
  };
  select.replaceChildren(new Option("—", ""), ...group("Yours", own), ...group("Shared with you", shared));
  select.value = state.collection?.collection.id ?? "";
}

function collectionLabel(summary) {
  const owner = summary.owner !== state.user?.name ? ` · by ${summary.owner}` : "";
  return `${summary.name || summary.id} · ${summary.n_members} members · ${summary.n_curves} curves${owner}`;
}

/** The shapes offered as new members (the shape library, several chosen at once). */
export function showMemberChoices(shapes) {
  const select = $("member-shapes");
  const chosen = new Set([...select.selectedOptions].map((option) => option.value));
  select.replaceChildren(
    ...shapes.map((s) => Object.assign(new Option(`${s.name} (${s.n_vertices} vertices)`, s.id), { selected: chosen.has(s.id) })),
  );
}

/** "Make template" needs an open session one may read whose curves become the template curves. */
export function showTemplateButton() {
  $("create-collection").disabled = !state.session?.curves.length || Boolean(state.guide);
}

/** The chosen collection: its overall progress, its members, and the controls that need it. */
export function showCollection() {
  const view = state.collection;
  $("collection-body").hidden = !view;
  showTemplateButton();
  if (!view) return;
  const { members } = view;
  const done = members.filter((m) => m.curves_total > 0 && m.curves_done === m.curves_total).length;
  const ready = members.filter((m) => m.basis === "ready").length;
  $("collection-progress").textContent =
    `${done} of ${members.length} members done (every template curve answered) · bases ready ${ready}/${members.length}`;
  $("member-list").replaceChildren(...members.map(memberItem));
  showMemberSelect(members);
  $("run-all").disabled = !members.some(hasCurves);
  $("add-members").disabled = !mayEditCollection();
  showGuide();
}

/** A member is ready to run once it has curves. */
export function hasCurves(member) {
  return member.curves_done + member.extra_curves > 0;
}

/** The member's name: its shape's. */
export function memberName(member) {
  return member.shape_name || state.shapeNames.get(member.shape) || member.shape;
}

/** Adding and removing members, starting runs: the collection's `may` (role and sharing together). */
function mayEditCollection() {
  return state.collection.may.includes("edit");
}

/** Who holds which role (GET .../roles); the grant and assign forms show to those who may grant. The assign form
 * offers those who may annotate. */
export function showRoles(roles) {
  $("collection-roles").textContent = `Roles: ${roles.map((r) => `${r.user} ${r.role}`).join(" · ")}`;
  const manages = Boolean(state.collection?.may.includes("manage"));
  $("grant-role").hidden = !manages;
  $("assign-member").hidden = !manages;
  const select = $("assign-user-select");
  const chosen = select.value;
  const annotators = roles.filter((r) => ANNOTATING_ROLES.includes(r.role)).map((r) => r.user);
  select.replaceChildren(new Option("no one", ""), ...annotators.map((user) => new Option(user, user)));
  if (annotators.includes(chosen)) select.value = chosen;
}

const ANNOTATING_ROLES = ["annotator", "manager", "owner"];

function showMemberSelect(members) {
  const select = $("assign-member-select");
  const chosen = select.value;
  select.replaceChildren(...members.map((m) => new Option(`${memberName(m)} (${m.id})`, m.id)));
  if (members.some((m) => m.id === chosen)) select.value = chosen;
}

/** The agreement between annotators (GET .../agreement; null: not asked for): the project's mean, then per member
 * its mean map distance, flagged above the threshold. */
export function showAgreement(report) {
  $("agreement-box").hidden = !report;
  if (!report) return;
  const distance = (value) => (value === null ? "—" : value.toFixed(4));
  const flagged = report.flagged.length ? ` · ${report.flagged.length} flagged for review` : "";
  $("agreement-summary").textContent = report.members.length
    ? `Agreement: mean map distance ${distance(report.map_distance)} (threshold ${report.threshold}, by sqrt(area))${flagged}`
    : "Agreement: no member is annotated twice with curves yet.";
  $("agreement-list").replaceChildren(
    ...report.members.map((entry) => {
      const item = document.createElement("li");
      item.dataset.member = entry.member;
      item.classList.toggle("flagged", entry.flagged);
      const member = state.collection.members.find((m) => m.id === entry.member);
      const pairs = entry.pairs.map((p) => `${p.a ?? "?"}/${p.b ?? "?"} ${distance(p.map_distance)}`).join(", ");
      const flag = entry.flagged ? " · over the threshold: review it" : "";
      item.textContent = `${member ? memberName(member) : ""} (${entry.member}) · ${distance(entry.map_distance)}${flag} · ${pairs}`;
      return item;
    }),
  );
  showChecks(report.checks, distance);
}

/** The annotators' accuracy on the check members (the report's `checks`, given to those who manage the collection
 * only; null: none or not theirs to see): the mean error and each annotator's, then per check member each
 * annotation's error against the truth, by sqrt(area). */
function showChecks(checks, distance) {
  $("check-summary").hidden = !checks;
  $("check-list").replaceChildren();
  if (!checks) return;
  const annotators = checks.annotators.map((a) => `${a.annotator} ${distance(a.error)} (${a.members})`).join(" · ");
  $("check-summary").textContent =
    `Check members: mean error ${distance(checks.error)} (by sqrt(area))${annotators ? ` · ${annotators}` : ""}`;
  $("check-list").replaceChildren(
    ...checks.members.map((entry) => {
      const item = document.createElement("li");
      item.dataset.member = entry.member;
      const member = state.collection.members.find((m) => m.id === entry.member);
      const errors = entry.annotations.map((a) => `${a.annotator ?? "?"} ${distance(a.error)}`).join(", ");
      item.textContent = `${member ? memberName(member) : ""} (${entry.member}) · check · ${errors || "not annotated yet"}`;
      return item;
    }),
  );
}

/** "My work" (GET /me/work): the members assigned to the user and the further annotations asked of them, what is
 * next first. */
export function showMyWork(items) {
  $("my-work-box").hidden = !items.length;
  $("my-work").replaceChildren(
    ...items.map((item, at) => {
      const entry = document.createElement("li");
      entry.dataset.collection = item.collection;
      entry.dataset.member = item.member;
      entry.dataset.session = item.session;
      entry.classList.toggle("done", item.done);
      const next = at === 0 && !item.done ? "next: " : "";
      const label = `${next}${item.collection_name || item.collection} · ${item.shape_name} (${item.member})`;
      const review = item.review === "open" ? "" : ` · ${REVIEW_LABELS[item.review]}`;
      const further = item.further ? " · further annotation" : "";
      entry.dataset.further = item.further;
      entry.textContent = `${label} · ${item.curves_done}/${item.curves_total} curves${review}${further}`;
      return entry;
    }),
  );
}

function memberItem(member) {
  const item = document.createElement("li");
  item.dataset.memberId = member.id;
  item.classList.toggle("current", state.guide?.member === member.id);
  item.classList.toggle("done", member.curves_total > 0 && member.curves_done === member.curves_total);
  const basis = member.basis === "ready" ? "" : ` · basis ${member.basis}`;
  const extra = member.extra_curves ? ` +${member.extra_curves} extra` : "";
  const run = member.last_run ? ` · run ${member.last_run.state}` : "";
  const assignee = state.collection.assignees[member.id];
  const by = assignee ? ` · ${assignee}` : "";
  const label = Object.assign(document.createElement("span"), { className: "member-label" });
  label.textContent =
    `${memberName(member)} (${member.id})${basis} · ${member.curves_done}/${member.curves_total} curves${extra}${run}${by}`;
  const open = Object.assign(document.createElement("button"), { type: "button", textContent: "Open" });
  open.dataset.action = "open";
  open.disabled = member.basis !== "ready";
  open.title = open.disabled ? "its basis is not ready yet" : "click its curves: template as source, member as target";
  const remove = Object.assign(document.createElement("button"), { type: "button", textContent: "Remove…" });
  remove.dataset.action = "remove";
  remove.disabled = !mayEditCollection();
  remove.title = "remove the member with its session, curves and refinement results (asks first)";
  item.append(label, reviewState(member), open, remove, ...reviewButtons(member));
  return item;
}

const REVIEW_LABELS = { open: "open", submitted: "submitted", changes_requested: "changes requested", accepted: "accepted" };

/** The member's review state (GET /collections/{id}: reviews), with who and when in its title. */
function reviewState(member) {
  const review = state.collection.reviews[member.id] ?? { state: "open" };
  const element = Object.assign(document.createElement("span"), { className: `review ${review.state}` });
  element.dataset.review = review.state;
  const comment = review.state === "changes_requested" && review.comment ? `: “${review.comment}”` : "";
  element.textContent = ` · ${REVIEW_LABELS[review.state]}${comment}`;
  const when = (seconds) => new Date(seconds * 1000).toLocaleString();
  const submitted = review.submitted_by ? `submitted by ${review.submitted_by} ${when(review.submitted_at)}` : "";
  const reviewed = review.reviewed_by ? `reviewed by ${review.reviewed_by} ${when(review.reviewed_at)}` : "";
  element.title = [submitted, reviewed].filter(Boolean).join("; ") || "not submitted for review yet";
  return element;
}

/** Submit (who may answer it, while open or sent back), Accept and Request changes (who may review). */
function reviewButtons(member) {
  const current = state.collection.reviews[member.id]?.state ?? "open";
  const may = state.collection.may;
  const button = (action, text, title) => {
    const element = Object.assign(document.createElement("button"), { type: "button", textContent: text, title });
    element.dataset.action = action;
    return element;
  };
  const buttons = [];
  if (["open", "changes_requested"].includes(current) && (may.includes("answer") || may.includes("answer_any"))) {
    buttons.push(button("submit", "Submit", "submit for review: its curves are locked until a reviewer decides"));
  }
  if (may.includes("review") && current === "submitted") {
    buttons.push(button("accept", "Accept", "accept the member's curves"));
  }
  if (may.includes("review") && ["submitted", "accepted"].includes(current)) {
    buttons.push(button("request-changes", "Request changes…", "send it back to its annotator with a comment"));
  }
  return buttons;
}

/** A member opened for guided clicking: its guide shows. */
export function openCollectionsPanel() {
  $("collections-panel").open = true;
}

/** The guide of the member being clicked: its name, the prompt, and the template curves (answered, current). */
export function showGuide() {
  const { guide } = state;
  $("guide").hidden = !guide;
  if (!guide) return;
  const member = state.collection.members.find((m) => m.id === guide.member);
  $("guide-member").textContent = `Member ${member ? memberName(member) : ""} (${guide.member}): answer the template curves on the target`;
  $("guide-prompt").textContent = pendingHint();
  const next = $("guide-next-member");
  next.disabled = nextMember() === null;
  next.classList.toggle("primary", guide.current === null);
  $("template-curves").replaceChildren(...templateCurves().map((curve) => templateItem(curve, guide.current)));
}

function templateItem(curve, current) {
  const item = document.createElement("li");
  item.dataset.templateCurve = curve.id;
  item.classList.toggle("current", curve.id === current);
  item.classList.toggle("answered", Boolean(curve.answer));
  const swatch = Object.assign(document.createElement("span"), { className: "swatch" });
  swatch.style.background = curveColor(curve.id);
  const label = Object.assign(document.createElement("span"), { className: "curve-label" });
  const answer = curve.answer ? `answered (${curve.answer.id})` : "not answered";
  label.textContent = `${curve.id}${curve.name ? ` '${curve.name}'` : ""} · ${answer}`;
  item.title = "Click to answer this template curve next (again: replaces the answer).";
  item.append(swatch, label);
  return item;
}

/** The member after the guided one (in list order, wrapping) whose basis is ready, preferring one with template
 * curves left to answer; null when there is none. */
export function nextMember() {
  const { members } = state.collection;
  const at = members.findIndex((m) => m.id === state.guide?.member);
  const after = [...members.slice(at + 1), ...members.slice(0, Math.max(at, 0))].filter((m) => m.basis === "ready");
  const unfinished = after.find((m) => m.curves_done < m.curves_total);
  return (unfinished ?? after[0])?.id ?? null;
}

/** The downloads of a finished run (or none: null). */
export function showRunLinks(links) {
  $("run-downloads").replaceChildren(
    ...Object.entries(links ?? {}).map(([name, href]) => {
      const item = document.createElement("li");
      item.append(Object.assign(document.createElement("a"), { href, download: name, textContent: name }));
      return item;
    }),
  );
}
