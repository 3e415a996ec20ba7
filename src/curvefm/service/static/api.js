// The curvefm HTTP API: JSON in and out, binary payloads as ArrayBuffer, every failure as an ApiError.
// Vertex ids in JSON are file ids; binary payloads (mesh, transfer, quality) have a row per drawn vertex (a big
// shape's display copy: transfer and quality are asked for with resolution=display). Whether the
// service can be reached goes to the store (state.connected) with every request, and a refused login
// (401) too (state.loggedOut). Requests carry the login cookie; the browser adds it.
import { decodeArrays } from "./mesh.js";
import { loggedOut, setConnected } from "./store.js";

export class ApiError extends Error {
  /** kind: the service's error kind (invalid, unauthenticated, forbidden, not_found, conflict, too_large) or
   * "network". */
  constructor(message, { status = 0, kind = "network" } = {}) {
    super(message);
    this.status = status;
    this.kind = kind;
  }
}

async function request(method, path, { json, body, as = "json", headers = {} } = {}) {
  const init = { method, headers: { ...headers } };
  if (json !== undefined) {
    init.body = JSON.stringify(json);
    init.headers["Content-Type"] = "application/json";
  } else if (body !== undefined) {
    init.body = body;
  }
  let response;
  try {
    response = await fetch(path, init);
  } catch (error) {
    setConnected(false);
    throw new ApiError(`cannot reach the service (${method} ${path}): ${error.message}`);
  }
  setConnected(true);
  if (response.status === 401) loggedOut();
  if (!response.ok) throw await errorFrom(response);
  if (as === "none") return null;
  if (as === "json") return response.json();
  if (as === "text") return response.text();
  if (as === "page") return { items: await response.json(), total: Number(response.headers.get("X-Total-Count")) };
  return { buffer: await response.arrayBuffer(), headers: response.headers };
}

async function errorFrom(response) {
  const text = await response.text();
  let kind = "invalid";
  let detail = text || response.statusText;
  try {
    const body = JSON.parse(text);
    kind = body.error ?? kind;
    detail = typeof body.detail === "string" ? body.detail : JSON.stringify(body.detail);
  } catch {
    // not JSON (a proxy's page, say): the text itself is the message
  }
  return new ApiError(detail, { status: response.status, kind });
}

const enc = encodeURIComponent;

/** An edit based on ``revision`` of the session: refused with 409 (the body's revision is the current one) when
 * someone changed the session since. */
const basedOn = (revision) => ({ "If-Match": `"${revision}"` });
const carried = (carry) => new URLSearchParams(carry ? { carry, resolution: "display" } : {});

function curvePath(id, curveId, carry) {
  const query = carried(carry);
  return `/sessions/${enc(id)}/curves/${enc(curveId)}${query.size ? `?${query}` : ""}`;
}

/** An edit's ``carried`` function as the transfer read gives it: { values, columns, revision, solveMs,
 * priorPending } (its 16-bit codes scaled back per column). */
export function decodeCarried(carried) {
  const text = atob(carried.codes);
  const codes = new Uint16Array(text.length / 2);
  for (let i = 0; i < codes.length; i++) codes[i] = text.charCodeAt(2 * i) | (text.charCodeAt(2 * i + 1) << 8);
  const { columns, offset, step } = carried;
  const values = new Float32Array(codes.length);
  for (let i = 0; i < codes.length; i++) values[i] = offset[i % columns] + step[i % columns] * codes[i];
  return {
    values,
    columns,
    revision: carried.revision,
    solveMs: carried.solve_ms,
    priorPending: carried.prior_pending,
  };
}

export const api = {
  health: () => request("GET", "/health"),
  /** Trade a token (the login URL's) for the login cookie; resolves to the user. */
  login: (token) => request("POST", "/auth/login", { headers: { Authorization: `Bearer ${token}` } }),
  logout: () => request("POST", "/auth/logout", { as: "none" }),
  me: () => request("GET", "/auth/me"),
  /** How one may log in besides a token: { single_sign_on: { label, login_url } | null }. */
  loginMethods: () => request("GET", "/auth/methods"),
  /** A new bearer token of the logged-in user (the old one stops working): { name, token }. */
  newToken: () => request("POST", "/auth/token"),
  plugins: () => request("GET", "/plugins"),

  shapes: () => request("GET", "/shapes"),
  shape: (id) => request("GET", `/shapes/${enc(id)}`),
  mesh: (id) => request("GET", `/shapes/${enc(id)}/mesh`, { as: "binary" }),
  uploadShape(file) {
    const form = new FormData();
    form.append("file", file, file.name);
    return request("POST", "/shapes", { body: form });
  },
  /** Where some vertices are (file ids): { positions: Float32Array n x 3, nearest_row: Uint32Array n }. */
  async points(id, fileIds) {
    const path = `/shapes/${enc(id)}/points`;
    const { buffer } = await request("POST", path, { json: { vertices: fileIds }, as: "binary" });
    return decodeArrays(buffer).arrays;
  },
  requestBasis: (id, k) => request("POST", `/shapes/${enc(id)}/bases`, { json: { k } }),

  sessions: () => request("GET", "/sessions"),
  /** The first `limit` sessions of their own (not a collection's members), the most recently changed first, whose
   * name or shape names contain `query` (when given): { items, total }. */
  sessionPage(limit, query = "") {
    const params = new URLSearchParams({ limit: String(limit), in_collection: "false" });
    if (query) params.set("q", query);
    return request("GET", `/sessions?${params}`, { as: "page" });
  },
  session: (id) => request("GET", `/sessions/${enc(id)}`),
  createSession: (body) => request("POST", "/sessions", { json: body }),
  shareSession: (id, sharing) => request("PATCH", `/sessions/${enc(id)}`, { json: { sharing } }),
  renameSession: (id, name) => request("PATCH", `/sessions/${enc(id)}`, { json: { name } }),
  deleteSession: (id) => request("DELETE", `/sessions/${enc(id)}`, { as: "none" }),
  /** Add a curve to revision ``revision`` of the session; undoing a delete gives back its id and place: { curveId,
   * position } (both optional). carry ("uv" or "xyz", or null): the answer's ``carried`` holds that function
   * through the new map at the display resolution (decode it with decodeCarried), which saves the transfer read. */
  addCurve(id, revision, spec, { curveId = null, position = null, carry = null } = {}) {
    const query = carried(carry);
    if (curveId !== null) query.set("curve_id", curveId);
    if (position !== null) query.set("position", String(position));
    const path = `/sessions/${enc(id)}/curves${query.size ? `?${query}` : ""}`;
    return request("POST", path, { json: spec, headers: basedOn(revision) });
  },
  replaceCurve: (id, revision, curveId, spec, carry = null) =>
    request("PUT", curvePath(id, curveId, carry), { json: spec, headers: basedOn(revision) }),
  deleteCurve: (id, revision, curveId, carry = null) =>
    request("DELETE", curvePath(id, curveId, carry), { headers: basedOn(revision) }),
  /** The URL of the session's changes as Server-Sent Events (GET /sessions/{id}/events), for an EventSource. */
  eventsUrl: (id) => `/sessions/${enc(id)}/events`,
  map: (id) => request("GET", `/sessions/${enc(id)}/map`),
  /** What the maps are now: { energy, weights, size, summary, reason } (see GET /sessions/{id}/solve). */
  solve: (id) => request("GET", `/sessions/${enc(id)}/solve`),
  /** function: uv | xyz | indicator (with vertices: source file ids). Resolves to { values, columns, revision,
   * solveMs, priorPending } (solveMs: the time the service spent solving the map for this read, 0 when already
   * solved; priorPending: the map of this revision will still improve once the landmark prior lands). */
  async transfer(id, fn, vertices = null) {
    const query = new URLSearchParams({ function: fn, resolution: "display" });
    if (vertices) query.set("vertices", vertices.join(","));
    const { buffer, headers } = await request("GET", `/sessions/${enc(id)}/transfer?${query}`, { as: "binary" });
    const columns = Number(headers.get("X-Shape").split(",")[1]);
    const revision = Number(headers.get("X-Revision"));
    return {
      values: new Float32Array(buffer),
      columns,
      revision,
      solveMs: Number(headers.get("X-Solve-Ms")),
      priorPending: headers.get("X-Prior-Pending") === "true",
    };
  },
  /** The next curve to draw (see GET /sessions/{id}/suggestion): { revision, source: [start, end], target:
   * [their images], prior_pending, path_source, path_target (the curve traced on each shape) }, file ids. With
   * ``ends`` ({ source, target } as the user moved them): those ends, traced again. */
  suggestion: (id, ends = null) => {
    const query = new URLSearchParams({ paths: "true" });
    if (ends) for (const side of ["source", "target"]) query.set(side, ends[side].join(","));
    return request("GET", `/sessions/${enc(id)}/suggestion?${query}`);
  },
  /** The live maps' round trip per drawn target vertex (see GET /sessions/{id}/quality): { drift: Float32Array,
   * score, worstTarget, worstSource (file ids clear of the curves), revision, priorPending (these figures will still
   * change once the landmark prior for this revision lands) }. */
  async quality(id) {
    const path = `/sessions/${enc(id)}/quality?resolution=display`;
    const { buffer, headers } = await request("GET", path, { as: "binary" });
    return {
      drift: new Float32Array(buffer),
      score: Number(headers.get("X-Score")),
      worstTarget: Number(headers.get("X-Worst-Target")),
      worstSource: Number(headers.get("X-Worst-Source")),
      revision: Number(headers.get("X-Revision")),
      priorPending: headers.get("X-Prior-Pending") === "true",
    };
  },
  refinements: (id) => request("GET", `/sessions/${enc(id)}/refinements`),
  refine: (id, converter, params) => request("POST", `/sessions/${enc(id)}/refine`, { json: { converter, params } }),

  collections: () => request("GET", "/collections"),
  collection: (id) => request("GET", `/collections/${enc(id)}`),
  /** body: { name, template, from_session } or { name, template, curves } (see POST /collections). */
  createCollection: (body) => request("POST", "/collections", { json: body }),
  addMembers: (id, shapes) => request("POST", `/collections/${enc(id)}/members`, { json: { shapes } }),
  /** Answer template curve ``answer.template_curve`` on a member with ``answer.target`` (member file ids); answering
   * it again replaces the earlier answer. Resolves to a curve edit, as addCurve. */
  answerCurve: (id, member, revision, answer, annotator = null) =>
    request("POST", `/collections/${enc(id)}/members/${enc(member)}/curves${annotator ? `?annotator=${enc(annotator)}` : ""}`, {
      json: answer,
      headers: basedOn(revision),
    }),
  removeMember: (id, member) => request("DELETE", `/collections/${enc(id)}/members/${enc(member)}`, { as: "none" }),
  /** Submit a member for review (every template curve answered); resolves to its review. */
  submitMember: (id, member) => request("POST", `/collections/${enc(id)}/members/${enc(member)}/submit`),
  /** decision: "accept" or "request_changes" (with a comment for the annotator); resolves to the member's review. */
  reviewMember: (id, member, decision, comment = "") =>
    request("POST", `/collections/${enc(id)}/members/${enc(member)}/review`, { json: { decision, comment } }),
  /** A member's review comments, oldest first: { id, side, vertex (a file id), text, author, reply_to, resolved_by }. */
  comments: (id, member) => request("GET", `/collections/${enc(id)}/members/${enc(member)}/comments`),
  /** body: { text, side, vertex } (a new thread) or { text, reply_to } (a reply); resolves to the comment. */
  addComment: (id, member, body) =>
    request("POST", `/collections/${enc(id)}/members/${enc(member)}/comments`, { json: body }),
  resolveComment: (id, member, comment, resolved) =>
    request("PATCH", `/collections/${enc(id)}/members/${enc(member)}/comments/${enc(comment)}`, { json: { resolved } }),
  deleteComment: (id, member, comment) =>
    request("DELETE", `/collections/${enc(id)}/members/${enc(member)}/comments/${enc(comment)}`, { as: "none" }),
  /** A run of the members that have curves (the others keep their previous run's jobs). */
  startRun: (id, converter, params) =>
    request("POST", `/collections/${enc(id)}/runs`, { json: { converter, params, only_ready: true } }),
  run: (id, run) => request("GET", `/collections/${enc(id)}/runs/${enc(run)}`),
  roles: (id) => request("GET", `/collections/${enc(id)}/roles`),
  grant: (id, user, role) => request("PUT", `/collections/${enc(id)}/roles/${enc(user)}`, { json: { role } }),
  /** Spread the members without an annotator among ``annotators`` (user names), the fewest first. */
  assign: (id, annotators, members) =>
    request("POST", `/collections/${enc(id)}/assign`, { json: { annotators, ...(members && { members }) } }),
  /** Assign one member to an annotator (user null: to no one); resolves to the member's progress. */
  assignMember: (id, member, user) =>
    request("PUT", `/collections/${enc(id)}/members/${enc(member)}/assignee`, { json: { user } }),
  /** Ask `user` for a further, independent annotation of a member (double annotation). */
  addAnnotation: (id, member, user) =>
    request("POST", `/collections/${enc(id)}/members/${enc(member)}/annotations`, { json: { user } }),
  /** Make a member a check member: its ground truth from a file (see PUT .../truth); resolves to its summary. */
  setTruth(id, member, file) {
    const form = new FormData();
    form.append("file", file, file.name);
    return request("PUT", `/collections/${enc(id)}/members/${enc(member)}/truth`, { body: form });
  },
  /** Agreement between annotators: per member annotated twice or more its mean map distance, flagged above the
   * threshold (see AgreementReport). */
  agreement: (id) => request("GET", `/collections/${enc(id)}/agreement`),
  /** The members assigned to the user in every collection, those not done first. */
  myWork: () => request("GET", "/me/work"),
  archiveUrl: (id, run, kind) => `/collections/${enc(id)}/runs/${enc(run)}/archive.${kind}`,

  job: (id) => request("GET", `/jobs/${enc(id)}`),
  cancelJob: (id) => request("DELETE", `/jobs/${enc(id)}`),
  text: (path) => request("GET", path, { as: "text" }),
};

/** Poll a job until it ends; onProgress(job) sees every state. Resolves with the finished job, rejects
 * with an ApiError carrying the job's readable error when it failed, was canceled or was lost (its message
 * says why). While the service, or its job queue (503), cannot be reached it keeps trying. */
export async function waitForJob(jobId, onProgress, intervalMs = 250) {
  for (;;) {
    let job;
    try {
      job = await api.job(jobId);
    } catch (error) {
      if (error.kind !== "network" && error.status !== 503) throw error;
      await sleep(2000); // the job goes on in the service; keep asking once it answers again
      continue;
    }
    onProgress(job);
    if (job.state === "finished") return job;
    if (["failed", "canceled", "lost"].includes(job.state)) {
      throw new ApiError(job.error?.message || `job ${job.state}: ${job.message}`, { kind: job.state });
    }
    await sleep(intervalMs);
  }
}

export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
