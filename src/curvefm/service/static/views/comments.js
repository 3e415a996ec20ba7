// The Review comments panel and the comments' markers: the open member's threads in order, replies under their
// first comment, resolved threads struck through; on each shape a pin at every thread's vertex, the chosen
// comment's thread in yellow.
import { mayReplyComment, mayStartComment, state } from "../store.js";
import { $ } from "./dom.js";
import { SIDES, viewports } from "./viewports.js";

export function showComments() {
  const view = state.comments;
  $("comments-panel").hidden = !view;
  const items = view?.items ?? [];
  const open = items.filter((c) => !c.reply_to && !c.resolved_by).length;
  const how = mayStartComment() ? " · Alt+click a vertex of either shape to comment there" : "";
  $("comments-summary").textContent = `${items.length} comments, ${open} open threads${how}`;
  $("comment-mode-label").hidden = !mayStartComment();
  $("comment-list").replaceChildren(...threaded(items).map((c) => commentItem(c, items)));
  for (const side of SIDES) viewports[side].setCommentMarkers(view ? markers(side, items) : []);
}

/** Threads in the order they started, each first comment followed by its replies. */
function threaded(items) {
  const firsts = items.filter((c) => !c.reply_to);
  return firsts.flatMap((first) => [first, ...items.filter((c) => c.reply_to === first.id)]);
}

function selectedThread(items) {
  const chosen = items.find((c) => c.id === state.selectedComment);
  return chosen ? (chosen.reply_to ?? chosen.id) : null;
}

function markers(side, items) {
  const firsts = items.filter((c) => c.side === side && !c.reply_to);
  const rows = state.shapes[side].points.rows(firsts.map((c) => c.vertex));
  const thread = selectedThread(items);
  return firsts.map((c, i) => ({ id: c.id, vertex: rows[i], selected: c.id === thread, resolved: Boolean(c.resolved_by) }));
}

function commentItem(comment, items) {
  const item = document.createElement("li");
  item.dataset.commentId = comment.id;
  const first = comment.reply_to ? items.find((c) => c.id === comment.reply_to) : comment;
  item.classList.toggle("reply", Boolean(comment.reply_to));
  item.classList.toggle("resolved", Boolean(first?.resolved_by));
  item.classList.toggle("selected", comment.id === state.selectedComment);
  const where = comment.side === "source" ? "template" : "member";
  const pin = Object.assign(document.createElement("span"), { className: "comment-pin" });
  pin.textContent = comment.reply_to ? "↳" : `● ${where} ${comment.vertex}`;
  const text = Object.assign(document.createElement("span"), { className: "comment-text" });
  text.textContent = `${comment.author ?? "?"}: ${comment.text}`;
  item.title = new Date(comment.created_at * 1000).toLocaleString();
  item.append(pin, text, ...commentButtons(comment));
  return item;
}

/** Reply and Resolve / Reopen on a thread's first comment; Delete on one's own comments. */
function commentButtons(comment) {
  const button = (action, textContent) => {
    const element = Object.assign(document.createElement("button"), { type: "button", textContent });
    element.dataset.action = action;
    return element;
  };
  const buttons = [];
  if (!comment.reply_to && mayReplyComment()) {
    buttons.push(button("reply", "Reply"), comment.resolved_by ? button("reopen", "Reopen") : button("resolve", "Resolve"));
  }
  if (comment.author === state.user?.name) buttons.push(button("delete", "Delete"));
  return buttons;
}
