// Review comments on the open session's collection member: read when a member's session or a collection opens,
// a new thread pinned by Alt+click (or any click while "Comment" is on) on a vertex of either shape (reviewers,
// managers, owners), and in the list: a click chooses one (its marker turns yellow), Reply, Resolve / Reopen (they
// and the member's annotator) and Delete (its author).
import { api } from "../api.js";
import { mayStartComment, reviewedMember, selectComment, setCommentMode, setComments, state } from "../store.js";
import { showComments } from "../views/comments.js";
import { report, toast } from "../views/messages.js";
import { SIDES } from "../views/viewports.js";

/** Read the comments of the open session's member (none: the panel hides) and show them. */
export async function refreshComments() {
  const member = reviewedMember();
  const sessionId = state.session?.id;
  let view = null;
  try {
    if (member) view = { ...member, items: await api.comments(member.collection, member.member) };
    if (view) await placeComments(view.items);
  } catch (error) {
    report(error, "The review comments could not be read");
  }
  if (state.session?.id !== sessionId) return;
  setComments(view);
  showComments();
}

/** Where the comments' vertices are drawn (a display copy may not draw them: the service tells, once). */
function placeComments(items) {
  return Promise.all(
    SIDES.map((side) => state.shapes[side].points.load(items.filter((c) => c.side === side).map((c) => c.vertex))),
  );
}

/** A click on a shape that pins a comment (Alt held, or "Comment" on) while a member's session is open: asks for the
 * text and starts a thread at that vertex. Returns whether the click was one. */
export function commentClick(side, vertex, event) {
  if (!state.comments || !(event.altKey || state.commentMode)) return false;
  if (!mayStartComment()) {
    toast("Comment threads are started by the collection's reviewers, managers and owners.", "error");
    return true;
  }
  const fileId = state.shapes[side].mesh.fileIds[vertex];
  const text = window.prompt(`Comment on vertex ${fileId} of the ${side === "source" ? "template" : "member"}:`);
  if (text?.trim()) addComment({ text, side, vertex: fileId });
  return true;
}

async function addComment(body) {
  const { collection, member } = state.comments;
  try {
    const made = await api.addComment(collection, member, body);
    selectComment(made.id);
    await refreshComments();
  } catch (error) {
    report(error, "The comment was not added");
  }
}

async function resolveComment(commentId, resolved) {
  const { collection, member } = state.comments;
  try {
    await api.resolveComment(collection, member, commentId, resolved);
    await refreshComments();
  } catch (error) {
    report(error, "The comment thread could not be changed");
  }
}

async function deleteComment(commentId) {
  if (!window.confirm("Delete this comment (a thread's first comment: with its replies)?")) return;
  const { collection, member } = state.comments;
  try {
    await api.deleteComment(collection, member, commentId);
    await refreshComments();
  } catch (error) {
    report(error, "The comment was not deleted");
  }
}

function reply(commentId) {
  const text = window.prompt("Reply:");
  if (text?.trim()) addComment({ text, reply_to: commentId });
}

const COMMENT_ACTIONS = {
  reply,
  resolve: (commentId) => resolveComment(commentId, true),
  reopen: (commentId) => resolveComment(commentId, false),
  delete: deleteComment,
};

/** A click in the comment list: a button acts on its comment; elsewhere on an entry, it is chosen. */
export function clickCommentList(event) {
  const item = event.target.closest("li[data-comment-id]");
  if (!item) return;
  const button = event.target.closest("button[data-action]");
  if (button) return COMMENT_ACTIONS[button.dataset.action](item.dataset.commentId);
  selectComment(item.dataset.commentId);
  showComments();
}

/** The "Comment" toggle: while on, a click on either shape pins a comment instead of entering a curve. */
export function toggleCommentMode(on) {
  setCommentMode(on);
}
