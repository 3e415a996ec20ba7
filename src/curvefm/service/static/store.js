// The UI's state: the one mutable object of the page. Any module may read `state`; only the functions below
// change it. subscribe(key, listener) hears of the changes that are announced (the connection, the login).

const noClicks = () => ({ points: { source: [], target: [] }, closed: { source: false, target: false } });

export const state = {
  plugins: { tracer: [], converter: [] }, // GET /plugins: { name, description, parameters (JSON schema) } each
  session: null, // the SessionRecord, kept in step with every edit
  shapes: { source: null, target: null }, // { info, mesh, diagonal } per side; the source also has uv, xyz
  ready: false, // a session is shown with its first texture drawn
  fn: "uv", // the carried function: uv (texture), xyz (coordinates as colour), indicator (a region)
  map: "functional", // or "pointwise": through the last refinement's map
  region: null, // { center, fileIds, indicator } on the source
  pickingRegion: false, // the next click on the source chooses the region
  pointwise: null, // { p2p: Int32Array (target internal -> source internal), revision, converter }
  texture: null, // the image carried as "uv" (a THREE texture)
  quality: null, // the live maps' round trip (api.quality) of some revision, or null
  solve: null, // what the live maps are (api.solve, or an edit's map.solve): { energy, weights, size, summary, reason }
  // the next curve the service suggests (api.suggestion; ends possibly moved by the user), or null; moving: the end
  // being moved ({ side, index }: its next click on that side places it), or null
  suggestion: null,
  showSuggestion: true,
  moving: null,
  showQuality: false, // the target is tinted by the round-trip drift and the weakest regions are ringed
  selected: null, // curve id drawn thicker
  // The clicks of the curve pair being entered, internal vertex ids per side. A plain click adds a point, and
  // a plain click after the first closes that side; Shift+click adds a waypoint. Clicking a closed side starts
  // it over. Sides may be entered in either order.
  pending: noClicks(),
  history: [], // edits that can be undone, newest last: { kind: add | remove | replace, curveId, spec, position }
  refineJob: null, // the id of the running refinement job
  pairInProgress: false, // the user is opening a pair (stop waiting for the demo's session)
  targetChosen: false, // the user chose the target shape (the lists no longer pick one)
  transferTicket: 0, // counts requests for the carried function: only the newest one's answer is shown
  connected: true, // the last request reached the service
  user: null, // GET /auth/me: { name, admin } once logged in
  loggedOut: false, // the service refused the page's credentials (none, expired, or the token changed)
  stats: { samples: [], last: null }, // click-to-texture timings (window.curvefmStats)
  shapeNames: new Map(), // shape id -> name, from the last GET /shapes
  collection: null, // the chosen collection as GET /collections/{id} shows it: { collection: record, members }
  // Guided clicking: the open session is a member's of state.collection, and target clicks answer the current
  // template curve (null: none left; clicks enter extra curves as in any session).
  // { collection: id, member: member id, current: template curve id or null, annotator: the user's name in a further
  // annotation of the member (their own session; null in the member's session) }
  guide: null,
  // The review comments of the open session's collection member (reviewedMember): { collection, member, items:
  // GET .../comments }, or null; the chosen one (its marker is ringed); whether a click on a shape pins a comment.
  comments: null,
  selectedComment: null,
  commentMode: false,
  editing: 0, // edits sent and not yet shown: the service's announced changes wait for them
  viewers: [], // the names of the users who have the open session open (GET /sessions/{id}/events), the page's too
  followed: null, // the session whose changes made elsewhere the page follows (controllers/live.js), or null
};

const listeners = new Map(); // key -> Set of listener(value)

export function subscribe(key, listener) {
  if (!listeners.has(key)) listeners.set(key, new Set());
  listeners.get(key).add(listener);
}

function announce(key) {
  for (const listener of listeners.get(key) ?? []) listener(state[key]);
}

// -- plugins, lists and the open session -------------------------------------------------------------------
export function setPlugins(plugins) {
  state.plugins = plugins;
}

/** A session was loaded with its shapes (a member's, guided by ``guide``, or a plain one): what belonged to the
 * session shown before is dropped. */
export function sessionOpened(session, shapes, guide = null) {
  Object.assign(state, { session, shapes, region: null, pickingRegion: state.fn === "indicator", pointwise: null });
  state.guide = guide;
  state.quality = null;
  state.solve = null;
  Object.assign(state, { suggestion: null, moving: null });
  Object.assign(state, { selected: null, map: "functional", history: storedHistory(session), pending: noClicks() });
}

/** Follow the changes made elsewhere to session ``sessionId`` (null: to none); controllers/live.js listens. */
export function setFollowed(sessionId) {
  state.followed = sessionId;
  announce("followed");
}

/** The service's record replaced ours (it changed elsewhere): the local undo history no longer applies. */
export function sessionReloaded(session) {
  state.session = session;
  state.history = [];
  storeHistory();
}

// The undo history outlives a reload of the page (not the tab): kept in sessionStorage with the revision it ends at,
// it comes back only while the session is still at that revision (a change from elsewhere makes it wrong).
const historyKey = (sessionId) => `curvefm.history.${sessionId}`;

function storeHistory() {
  const { session, history } = state;
  try {
    sessionStorage.setItem(historyKey(session.id), JSON.stringify({ revision: session.revision, history }));
  } catch {
    // storage full or disabled: undo still works until the page is reloaded
  }
}

function storedHistory(session) {
  try {
    const stored = JSON.parse(sessionStorage.getItem(historyKey(session.id)) ?? "null");
    return stored?.revision === session.revision ? stored.history : [];
  } catch {
    return [];
  }
}

/** What the live maps are now: the energy, its weights, the size handed out and why (GET /sessions/{id}/solve). */
export function setSolve(solve) {
  state.solve = solve;
}

export function setReady(ready) {
  state.ready = ready;
}

export function setPairInProgress(inProgress) {
  state.pairInProgress = inProgress;
}

export function setShapeNames(shapes) {
  state.shapeNames = new Map(shapes.map((shape) => [shape.id, shape.name]));
}

export function chooseTarget() {
  state.targetChosen = true;
}

// -- curves --------------------------------------------------------------------------------------------------
/** A curve was added at ``position`` in the list (default: last). */
export function curveAdded(curve, position = state.session.curves.length) {
  state.session.curves.splice(position, 0, curve);
  state.session.next_curve = Math.max(state.session.next_curve, Number(curve.id.slice(1)) + 1);
}

export function curveRemoved(curveId) {
  state.session.curves = state.session.curves.filter((c) => c.id !== curveId);
  if (state.selected === curveId) state.selected = null;
}

export function curveReplaced(curveId, curve) {
  state.session.curves = state.session.curves.map((c) => (c.id === curveId ? curve : c));
}

/** The session's revision after one of the page's edits (its undo history is stored with it). */
export function setRevision(revision) {
  state.session.revision = revision;
  storeHistory();
}

export function selectCurve(curveId) {
  state.selected = curveId;
}

export function clickPending(side, vertex, waypoint) {
  const { points, closed } = state.pending;
  if (closed[side]) {
    points[side] = [];
    closed[side] = false;
  }
  points[side].push(vertex);
  if (!waypoint && points[side].length >= 2) closed[side] = true;
}

export function clearPending() {
  state.pending = noClicks();
}

/** Both sides of the pending curve are closed: it can be added. */
export function pendingComplete() {
  return state.pending.closed.source && state.pending.closed.target;
}

export function pendingEmpty() {
  return state.pending.points.source.length === 0 && state.pending.points.target.length === 0;
}

/** Remember an edit for undo: kind add | remove | replace, curve as it was before (after, for add), and its place in
 * the list before the edit (a deleted curve comes back there). */
export function recordEdit(kind, curve, position) {
  state.history.push({ kind, curveId: curve.id, spec: curve.spec, position });
}

/** The newest edit was undone. */
export function dropNewestEdit() {
  state.history.pop();
}

export function editStarted() {
  state.editing += 1;
}

export function editEnded() {
  state.editing -= 1;
  announce("editing");
}

/** Who has the open session open now (its event stream says). */
export function setViewers(names) {
  state.viewers = names;
}

// -- collections and guided clicking -------------------------------------------------------------------------
export function setCollection(view) {
  state.collection = view;
  if (state.guide && state.guide.collection !== view?.collection.id) state.guide = null;
}

/** The collection member whose session is open: the guided one, else the open collection's member of that session;
 * { collection, member } or null. */
export function reviewedMember() {
  if (state.guide) return { collection: state.guide.collection, member: state.guide.member };
  const member = state.collection?.members.find((m) => m.session === state.session?.id);
  return member ? { collection: state.collection.collection.id, member: member.id } : null;
}

/** The user may start comment threads on the open collection's members (its `may`: review). */
export function mayStartComment() {
  return Boolean(state.collection?.may.includes("review"));
}

/** The user may reply to comments and resolve threads: who may start them, or answer the open member. */
export function mayReplyComment() {
  return mayStartComment() || mayEdit();
}

export function setComments(view) {
  state.comments = view;
  if (!view?.items.some((c) => c.id === state.selectedComment)) state.selectedComment = null;
}

export function selectComment(commentId) {
  state.selectedComment = commentId;
}

export function setCommentMode(on) {
  state.commentMode = on;
}

export function setCurrentTemplateCurve(curveId) {
  state.guide.current = curveId;
}

/** The member session's curve answering template curve ``templateId``, or undefined. */
export function answerOf(templateId) {
  return state.session.curves.find((curve) => curve.spec.template_curve === templateId);
}

/** The guided collection's template curves ({ id, name, path, answer: the member's curve or undefined }); none
 * when no member is guided. */
export function templateCurves() {
  if (!state.guide || !state.collection) return [];
  return state.collection.collection.curves.map((curve) => ({ ...curve, answer: answerOf(curve.id) }));
}

/** Target clicks answer the current template curve: a member is guided, a template curve is current, and no
 * source point was clicked (a click on the source first starts an extra curve, entered on both sides). */
export function answeringTemplate() {
  return Boolean(state.guide?.current) && state.pending.points.source.length === 0;
}

// -- what the surfaces show ----------------------------------------------------------------------------------
export function setFunction(fn) {
  state.fn = fn;
  state.pickingRegion = fn === "indicator" && !state.region;
}

export function setRegion(region) {
  state.region = region;
  state.pickingRegion = false;
}

export function setPickingRegion(picking) {
  state.pickingRegion = picking;
}

export function setMap(map) {
  state.map = map;
}

export function setPointwise(pointwise) {
  state.pointwise = pointwise;
}

export function setQuality(quality) {
  state.quality = quality;
}

/** The quality figures (status line drift, overlay, where to click next) describe an older map than the session's
 * now: measured at an older revision, or before the landmark prior for this one landed. */
export function qualityStale() {
  const { quality, session } = state;
  return Boolean(quality && (quality.priorPending || quality.revision !== session?.revision));
}

export function setSuggestion(suggestion) {
  state.suggestion = suggestion;
  state.moving = null;
}

export function setShowSuggestion(show) {
  state.showSuggestion = show;
}

/** The next click on ``side`` places end ``index`` (0: start, 1: end) of the suggestion; null: none is moved. */
export function setMoving(moving) {
  state.moving = moving;
}

/** Move an end of the suggestion to ``fileId``; its traced paths no longer join its ends until traced again. */
export function moveSuggestedEnd(side, index, fileId) {
  state.suggestion[side][index] = fileId;
  state.suggestion.path_source = state.suggestion.path_target = null;
  state.moving = null;
}

/** The paths traced between the suggestion's ends as they are now. */
export function setSuggestedPaths(traced) {
  Object.assign(state.suggestion, { path_source: traced.path_source, path_target: traced.path_target });
}

export function setShowQuality(show) {
  state.showQuality = show;
}

export function setTexture(texture) {
  state.texture = texture;
}

/** A new request for the carried function: returns its ticket (see state.transferTicket). */
export function nextTransferTicket() {
  state.transferTicket += 1;
  return state.transferTicket;
}

// -- jobs, the connection, timings ---------------------------------------------------------------------------
export function setRefineJob(jobId) {
  state.refineJob = jobId;
}

// -- the login ----------------------------------------------------------------------------------------------
export function loggedIn(user) {
  state.user = user;
  state.loggedOut = false;
  announce("login");
}

/** The service answered 401: the page has no valid login (any more). */
export function loggedOut() {
  if (state.loggedOut) return;
  state.user = null;
  state.loggedOut = true;
  announce("login");
}

/** The user may share and delete the open session: its owner, or an admin. */
export function mayManage() {
  const { user, session } = state;
  return Boolean(user && session && (user.admin || session.owner === user.name));
}

/** The user may change the open session's curves: as its owner or sharing allow, or, for a member session of the
 * open collection, as their role there does. */
export function mayEdit() {
  return mayManage() || state.session?.sharing === "edit" || mayAnswerOpenMember() || answersFurther();
}

/** The open session is the user's own further annotation of the guided member. */
function answersFurther() {
  return Boolean(state.guide?.annotator) && state.guide.annotator === state.user?.name;
}

function mayAnswerOpenMember() {
  const view = state.collection;
  const member = view?.members.find((m) => m.session === state.session?.id);
  return Boolean(member && mayAnswer(view, member.id));
}

/** The user may answer the member's template curves (GET /collections/{id}'s `may`): every member with
 * `answer_any`; with `answer`, any while no member is assigned, else those assigned to them. */
export function mayAnswer(view, memberId) {
  if (view.may.includes("answer_any")) return true;
  const assigning = Object.keys(view.assignees).length > 0;
  return view.may.includes("answer") && (!assigning || view.assignees[memberId] === state.user?.name);
}

export function sessionShared(record) {
  state.session.sharing = record.sharing;
  setRevision(record.revision);
}

export function sessionRenamed(record) {
  state.session.name = record.name;
  setRevision(record.revision);
}

export function setConnected(connected) {
  if (connected === state.connected) return;
  state.connected = connected;
  announce("connected");
}

/** One click-to-texture timing, in milliseconds rounded to 0.1. */
export function recordSample(sample) {
  for (const key of ["totalMs", "editMs", "transferMs", "drawMs"]) sample[key] = Math.round(sample[key] * 10) / 10;
  state.stats.samples.push(sample);
  state.stats.last = sample;
}
