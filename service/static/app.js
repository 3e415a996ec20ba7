// The curvefm web UI: the interactive loop of curve-constrained functional maps. Click corresponding curves on
// the source and the target; after every edit the target shows a source function carried by the map.
import { api, onConnectionChange, sleep, waitForJob } from "./api.js";
import { curveColor, History, PendingCurve, renderCurveList } from "./curves.js";
import { listJobFiles, npyBlob, saveBlob } from "./downloads.js";
import { parametersForm } from "./forms.js";
import {
  bounds,
  checkerboardTexture,
  imageTexture,
  pullBack,
  rampColors,
  regionAround,
  rgbColors,
  xyzValues,
} from "./functions.js";
import { decodeMesh, pointwiseMap } from "./mesh.js";
import { banner, ProgressRow, toast } from "./messages.js";
import { chooseAxes, drawn, Viewport } from "./viewer.js";

const $ = (id) => document.getElementById(id);
const COLUMNS = { uv: 2, xyz: 3, indicator: 1 };
const SIDES = ["source", "target"];

const state = {
  session: null, // the SessionRecord, kept in step with every edit
  shapes: { source: null, target: null }, // { info, mesh, diagonal } per side; the source also has uv, xyz
  ready: false, // a session is shown with its first texture drawn
  fn: "uv", // the carried function: uv (texture), xyz (coordinates as colour), indicator (a region)
  map: "functional", // or "pointwise": through the last refinement's map
  region: null, // { center, fileIds, indicator } on the source
  pickingRegion: false,
  pointwise: null, // { p2p: Int32Array (target internal -> source internal), revision, converter }
  texture: checkerboardTexture(),
  selected: null, // curve id drawn thicker
  refineJob: null,
  pairInProgress: false, // the user is opening a pair (stop waiting for the demo's session)
};
const pending = new PendingCurve();
const history = new History();
const stats = { samples: [], last: null };
let feedbackTicket = 0;
let readTracerParams = () => ({});
let readConverterParams = () => ({});
let connected = true;

const views = {
  source: new Viewport($("source-view"), (vertex, event) => onPick("source", vertex, event)),
  target: new Viewport($("target-view"), (vertex, event) => onPick("target", vertex, event)),
};
linkCameras();

// Hooks for tests and benchmarks: ids are file ids, positions client pixels.
window.curvefmStats = stats;
window.curvefm = {
  get sessionId() {
    return state.session?.id ?? null;
  },
  get ready() {
    return state.ready;
  },
  vertexToScreen(side, fileId) {
    const { mesh } = state.shapes[side];
    return views[side].vertexToScreen(mesh.fileToInternal[fileId]);
  },
  screenToVertex(side, x, y) {
    const vertex = views[side].pick(x, y);
    return vertex < 0 ? null : state.shapes[side].mesh.fileIds[vertex];
  },
};

start();

// -- start-up and sessions ---------------------------------------------------------------------------------
async function start() {
  bindControls();
  onConnectionChange(connectionChanged);
  try {
    await loadPlugins();
    const { sessions } = await refreshLists();
    const id = new URLSearchParams(window.location.search).get("session") ?? sessions[0]?.id;
    if (id) await openSession(id);
    else await waitForFirstSession();
  } catch (error) {
    report(error, "The UI could not start");
    loading(`The UI could not start: ${error.message}`);
  }
}

async function loadPlugins() {
  const plugins = await api.plugins();
  fillPluginSelect($("tracer-select"), plugins.tracer, $("tracer-params"), (read) => (readTracerParams = read));
  fillPluginSelect($("converter-select"), plugins.converter, $("converter-params"), (read) => {
    readConverterParams = read;
  });
}

function fillPluginSelect(select, plugins, paramsBox, setReader) {
  select.replaceChildren(...plugins.map((p) => Object.assign(new Option(p.name, p.name), { title: p.description })));
  const preferred = plugins.find((p) => p.name === "geodesic" || p.name === "nearest-neighbor");
  if (preferred) select.value = preferred.name;
  const showParams = () => {
    paramsBox.replaceChildren();
    setReader(parametersForm(paramsBox, plugins.find((p) => p.name === select.value)?.parameters));
  };
  select.addEventListener("change", showParams);
  showParams();
}

async function refreshLists() {
  const [shapes, sessions] = await Promise.all([api.shapes(), api.sessions()]);
  for (const [select, role] of [[$("source-select"), "source"], [$("target-select"), "target"]]) {
    const previous = select.value || state.session?.[role];
    select.replaceChildren(...shapes.map((s) => new Option(`${s.name} (${s.n_vertices} v)`, s.id)));
    if (shapes.some((s) => s.id === previous)) select.value = previous;
  }
  if (!state.session && shapes.length > 1 && !$("target-select").dataset.touched) $("target-select").selectedIndex = 1;
  const sessionSelect = $("session-select");
  sessionSelect.replaceChildren(
    new Option("—", ""),
    ...sessions.map((s) => new Option(`${s.name || s.id} · ${s.n_curves} curves · k=${s.k}`, s.id)),
  );
  sessionSelect.value = state.session?.id ?? "";
  return { shapes, sessions };
}

/** No session yet (e.g. the demo still computing its bases): poll until one appears, unless the user
 * starts a pair of their own meanwhile. The shape lists are rebuilt only when the store changed. */
async function waitForFirstSession() {
  $("pair-panel").open = true;
  loading(
    "No session yet. Pick two shapes (or upload them) and open the pair; " +
      "the demo of `curvefm serve --demo` opens by itself once it is ready.",
  );
  let known = "";
  while (!state.session && !state.pairInProgress) {
    await sleep(1500);
    try {
      const [shapes, sessions] = await Promise.all([api.shapes(), api.sessions()]);
      const now = [...shapes, ...sessions].map((item) => item.id).join();
      if (now !== known) await refreshLists();
      known = now;
      if (sessions.length && !state.session && !state.pairInProgress) await openSession(sessions[0].id);
    } catch (error) {
      if (error.kind !== "network") throw error;
    }
  }
}

async function openSession(id) {
  const url = new URL(window.location.href);
  url.searchParams.set("session", id);
  window.history.replaceState(null, "", url);
  state.ready = false;
  loading("Loading the session…");
  try {
    const session = await api.session(id);
    const [source, target] = await Promise.all(SIDES.map((side) => loadShape(session[side], side === "source")));
    state.session = session;
    state.shapes = { source, target };
    Object.assign(state, { region: null, pickingRegion: state.fn === "indicator", pointwise: null, selected: null });
    state.map = "functional";
    history.clear();
    pending.clear();
    listJobFiles($("downloads"), {});
    $("refine-progress").replaceChildren();
    setPointwiseAvailable(false);
    for (const side of SIDES) {
      views[side].setMesh(state.shapes[side].mesh);
      $(`${side}-view`).querySelector(".shape-name").textContent =
        `${state.shapes[side].info.name} · ${state.shapes[side].info.n_vertices} vertices`;
    }
    orientViews();
    showCurves();
    showPending();
    showSource();
    paint(views.target, state.fn, await carriedRows());
    for (const side of SIDES) views[side].warmUp();
    await drawn(views.target);
    loading(null);
    state.ready = true;
    $("session-select").value = id;
    $("source-select").value = session.source;
    $("target-select").value = session.target;
    const title = `${session.name || session.id}: ${source.info.name} → ${target.info.name} · k=${session.k}`;
    $("session-title").textContent = title;
    updateStatus();
  } catch (error) {
    report(error, `Session ${id} could not be opened`);
    loading(`Session ${id} could not be opened: ${error.message}`);
    $("pair-panel").open = true;
  }
}

async function loadShape(id, withFunctions) {
  const [info, payload] = await Promise.all([api.shape(id), api.mesh(id)]);
  const mesh = decodeMesh(payload.buffer);
  const shape = { info, mesh, diagonal: diagonal(mesh.vertices) };
  if (withFunctions) Object.assign(shape, { uv: mesh.texcoords, xyz: xyzValues(mesh.vertices) });
  return shape;
}

function diagonal(vertices) {
  const { low, high } = bounds(vertices);
  return Math.hypot(high[0] - low[0], high[1] - low[1], high[2] - low[2]);
}

/** Open a new session on the chosen pair: request missing bases, show their jobs, then create it. */
async function openPair() {
  const source = $("source-select").value;
  const target = $("target-select").value;
  const k = Number($("k-input").value);
  if (!source || !target) return toast("Upload or pick two shapes first.", "error");
  const box = $("pair-progress");
  box.replaceChildren();
  state.pairInProgress = true;
  $("open-pair").disabled = true;
  try {
    await Promise.all([...new Set([source, target])].map((id) => ensureBasis(id, k, box)));
    const session = await api.createSession({ source, target, k });
    await refreshLists();
    await openSession(session.id);
  } catch (error) {
    report(error, "The pair could not be opened");
  } finally {
    state.pairInProgress = false;
    $("open-pair").disabled = false;
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

async function upload(input) {
  const [file] = input.files;
  if (!file) return;
  const row = new ProgressRow($("pair-progress"), `upload ${file.name}`);
  try {
    const shape = await api.uploadShape(file);
    row.finish(`${shape.name}: ${shape.n_vertices} vertices`);
    const previous = $("target-select").value;
    await refreshLists();
    if (previous && previous !== shape.id) $("source-select").value = previous; // two uploads make a pair
    $("target-select").value = shape.id;
    $("target-select").dataset.touched = "yes";
    const warnings = shape.report.warnings ?? [];
    toast(`Uploaded ${shape.name}${warnings.length ? ` (${warnings.join("; ")})` : ""}. Pick the pair and open it.`);
  } catch (error) {
    row.finish(`rejected: ${error.message}`, false);
    report(error, `The upload of ${file.name} was rejected`);
  } finally {
    input.value = "";
  }
}

// -- clicking curves ---------------------------------------------------------------------------------------
function onPick(side, vertex, event) {
  if (!state.ready) return;
  if (state.pickingRegion) {
    if (side === "source") setRegion(vertex, event.timeStamp);
    return;
  }
  pending.click(side, vertex, event.shiftKey);
  if (pending.complete) addCurve(event.timeStamp);
  else showPending([side]);
}

function tracerChoice() {
  return { tracer: $("tracer-select").value, tracer_params: readTracerParams() };
}

function fileIds(side, internalIds) {
  return internalIds.map((vertex) => state.shapes[side].mesh.fileIds[vertex]);
}

function addCurve(clickTime) {
  const spec = {
    source: fileIds("source", pending.points.source),
    target: fileIds("target", pending.points.target),
    ...tracerChoice(),
  };
  pending.clear(); // its markers stay until the traced curve replaces them, in the frame with the new texture
  $("hint").textContent = "Tracing…";
  return runEdit(clickTime, "add", "The curve was not added", async () => {
    const edit = await edits.add(spec);
    history.added(edit.curve);
    return edit;
  });
}

function removeCurve(curveId, clickTime) {
  const curve = state.session.curves.find((c) => c.id === curveId);
  return runEdit(clickTime, "delete", `Curve ${curveId} was not deleted`, async () => {
    const edit = await edits.remove(curveId);
    history.removed(curve);
    return edit;
  });
}

function retraceCurve(curveId, clickTime) {
  const previous = state.session.curves.find((c) => c.id === curveId);
  const spec = { ...previous.spec, ...tracerChoice() };
  return runEdit(clickTime, "re-trace", `Curve ${curveId} was not re-traced`, async () => {
    const edit = await edits.replace(curveId, spec);
    history.replaced(previous);
    return edit;
  });
}

function undo(clickTime) {
  if (history.size === 0) return null;
  return runEdit(clickTime, "undo", "The last edit could not be undone", () => history.undo(edits));
}

/** The session's edits: call the service, then keep the local record in step with its answer. */
const edits = {
  async add(spec) {
    const edit = await api.addCurve(state.session.id, spec);
    state.session.curves.push(edit.curve);
    state.session.next_curve = Math.max(state.session.next_curve, Number(edit.curve.id.slice(1)) + 1);
    return edit;
  },
  async remove(curveId) {
    const edit = await api.deleteCurve(state.session.id, curveId);
    state.session.curves = state.session.curves.filter((c) => c.id !== curveId);
    if (state.selected === curveId) state.selected = null;
    return edit;
  },
  async replace(curveId, spec) {
    const edit = await api.replaceCurve(state.session.id, curveId, spec);
    state.session.curves = state.session.curves.map((c) => (c.id === curveId ? edit.curve : c));
    return edit;
  },
};

/** Run one edit, show it, and time it from the click to the frame that shows the new texture. The curves
 * and the texture change in one frame: a software renderer pays for every frame. */
async function runEdit(clickTime, kind, failure, perform) {
  const sessionId = state.session.id;
  try {
    const edit = await perform();
    const editedAt = performance.now();
    if (state.session?.id !== sessionId) return;
    state.session.revision = edit.map.revision;
    if (state.map === "pointwise") selectMap("functional"); // the refined map belongs to an older revision
    const rows = await carriedRows();
    const fetchedAt = performance.now();
    showCurves();
    showPending();
    if (rows === null) return; // a newer edit's texture is on its way
    paint(views.target, state.fn, rows);
    const drawnAt = await drawn(views.target);
    recordSample({
      kind,
      revision: edit.map.revision,
      totalMs: drawnAt - clickTime,
      editMs: editedAt - clickTime,
      transferMs: fetchedAt - editedAt,
      drawMs: drawnAt - fetchedAt,
      solveMs: edit.map.solve_ms,
    });
  } catch (error) {
    showPending();
    report(error, failure);
    if (error.kind === "not_found" || error.kind === "conflict") await resync();
  } finally {
    updateStatus();
  }
}

function recordSample(sample) {
  for (const key of ["totalMs", "editMs", "transferMs", "drawMs"]) sample[key] = Math.round(sample[key] * 10) / 10;
  stats.samples.push(sample);
  stats.last = sample;
}

/** Markers of the clicks so far (redrawing only the given sides), the hint, the cancel button. */
function showPending(sides = SIDES) {
  const color = curveColor(`c${state.session?.next_curve ?? 1}`);
  for (const side of sides) views[side].setMarkers(pending.points[side].map((vertex) => ({ vertex, color })));
  $("hint").textContent = state.pickingRegion ? "Click the source to choose the region." : pending.hint();
  $("cancel-pending").disabled = pending.empty;
}

function showCurves() {
  const { curves } = state.session;
  for (const side of SIDES) {
    const { mesh } = state.shapes[side];
    views[side].setCurves(
      curves.map((curve) => ({
        key: `${curve.id}:${curve.tracer}:${curve[`path_${side}`].length}`,
        color: curveColor(curve.id),
        path: curve[`path_${side}`].map((id) => mesh.fileToInternal[id]),
        emphasis: curve.id === state.selected,
      })),
    );
  }
  renderCurveList($("curve-list"), curves, state.selected, {
    select(id) {
      state.selected = id;
      showCurves();
    },
    retrace: retraceCurve,
    remove: removeCurve,
  });
  $("undo-button").disabled = history.size === 0;
  $("refine-button").disabled = curves.length === 0;
}

// -- feedback: what the surfaces show ----------------------------------------------------------------------
function sourceValues(fn) {
  const source = state.shapes.source;
  if (fn === "uv") return source.uv;
  if (fn === "xyz") return source.xyz;
  return state.region?.indicator ?? new Float32Array(source.mesh.nVertices);
}

function paint(view, fn, rows) {
  if (fn === "uv") view.showTexture(state.texture, rows);
  else if (fn === "xyz") view.showColors((out) => rgbColors(rows, out));
  else view.showColors((out) => rampColors(rows, out));
}

function showSource() {
  paint(views.source, state.fn, sourceValues(state.fn));
}

/** The chosen function carried to the target (rows per target vertex), through the live map from the service
 * or through the refined pointwise map; null when a newer request started meanwhile (its answer wins). */
async function carriedRows() {
  const ticket = ++feedbackTicket;
  const { fn } = state;
  if (fn === "indicator" && !state.region) return new Float32Array(state.shapes.target.mesh.nVertices);
  if (state.map === "pointwise") return pullBack(sourceValues(fn), COLUMNS[fn], state.pointwise.p2p);
  const vertices = fn === "indicator" ? state.region.fileIds : null;
  const { values } = await api.transfer(state.session.id, fn, vertices);
  return ticket === feedbackTicket ? values : null;
}

async function showFeedback(clickTime = null, kind = "view") {
  try {
    showSource();
    const rows = await carriedRows();
    if (rows === null) return;
    const fetchedAt = performance.now();
    paint(views.target, state.fn, rows);
    if (clickTime === null) return;
    const drawnAt = await drawn(views.target);
    recordSample({
      kind,
      revision: state.session.revision,
      totalMs: drawnAt - clickTime,
      editMs: 0,
      transferMs: fetchedAt - clickTime,
      drawMs: drawnAt - fetchedAt,
    });
    updateStatus();
  } catch (error) {
    report(error, "The target could not be updated");
  }
}

function selectFunction(fn) {
  state.fn = fn;
  $("region-controls").hidden = fn !== "indicator";
  state.pickingRegion = fn === "indicator" && !state.region;
  showPending();
  showFeedback();
}

function setRegion(center, clickTime) {
  const { mesh, diagonal: size } = state.shapes.source;
  const radius = (Number($("region-radius").value) / 100) * size;
  const { ids, indicator } = regionAround(mesh.vertices, center, radius);
  state.region = { center, indicator, fileIds: ids.map((i) => mesh.fileIds[i]) };
  state.pickingRegion = false;
  showPending();
  showFeedback(clickTime, "region");
}

function selectMap(map) {
  state.map = map;
  document.querySelector(`input[name="map"][value="${map}"]`).checked = true;
}

function setPointwiseAvailable(pointwise) {
  const radio = document.querySelector('input[name="map"][value="pointwise"]');
  radio.disabled = !pointwise;
  $("pointwise-label").textContent = pointwise
    ? `Pointwise (${pointwise.converter}, revision ${pointwise.revision})`
    : "Pointwise (refine first)";
  if (!pointwise) selectMap("functional");
}

function orientViews() {
  const axes = chooseAxes(state.shapes.source.mesh.vertices, $("up-select").value);
  const [source, target] = SIDES.map((side) => views[side].orient(axes));
  const both = source.max(target); // one camera distance fits both, so linked cameras frame both shapes
  for (const side of SIDES) views[side].resetCamera(both);
}

function linkCameras() {
  let following = false;
  for (const [side, other] of [["source", "target"], ["target", "source"]]) {
    views[side].controls.addEventListener("change", () => {
      if (following || !$("link-cameras").checked) return;
      following = true;
      views[other].copyCamera(views[side]);
      following = false;
    });
  }
}

async function useTextureImage(input) {
  const [file] = input.files;
  if (!file) return;
  try {
    state.texture = await imageTexture(file);
    if (!state.shapes.source?.info.has_uv) {
      toast("The source has no texture coordinates of its own: the image is laid on generated cylindrical ones.");
    }
    if (state.ready) showFeedback();
  } catch (error) {
    report(error, "The texture image could not be used");
  } finally {
    input.value = "";
  }
}

// -- refine and export -------------------------------------------------------------------------------------
async function refine() {
  const converter = $("converter-select").value;
  const row = new ProgressRow($("refine-progress"), `${converter} (revision ${state.session.revision})`);
  $("refine-button").disabled = true;
  try {
    const job = await api.refine(state.session.id, converter, readConverterParams());
    state.refineJob = job.id;
    $("cancel-refine").hidden = false;
    const done = await waitForJob(job.id, (update) => row.update(update));
    row.finish(`finished in ${(done.ended_at - done.started_at).toFixed(1)} s`);
    listJobFiles($("downloads"), done.links);
    const text = await api.text(done.links["map_target_to_source.txt"]);
    const p2p = pointwiseMap(text, state.shapes.source.mesh, state.shapes.target.mesh);
    state.pointwise = { p2p, revision: done.result.revision, converter };
    setPointwiseAvailable(state.pointwise);
    selectMap("pointwise");
    showFeedback();
  } catch (error) {
    row.finish(`failed: ${error.message}`, false);
    report(error, "The refinement did not finish");
  } finally {
    state.refineJob = null;
    $("cancel-refine").hidden = true;
    $("refine-button").disabled = !state.session?.curves.length;
  }
}

async function downloadLiveMap() {
  try {
    const map = await api.map(state.session.id);
    saveBlob(npyBlob(map.C_source_to_target), `C_source_to_target_${state.session.id}_r${map.revision}.npy`);
  } catch (error) {
    report(error, "The map could not be downloaded");
  }
}

// -- status, errors and the connection ---------------------------------------------------------------------
function updateStatus() {
  const parts = [];
  if (state.session) parts.push(`revision ${state.session.revision}`, `${state.session.curves.length} curves`);
  const last = stats.last;
  if (last) {
    parts.push(
      `click→texture ${last.totalMs.toFixed(0)} ms (${last.kind}: edit ${last.editMs.toFixed(0)} · transfer ` +
        `${last.transferMs.toFixed(0)} · draw ${last.drawMs.toFixed(0)})`,
    );
    if (last.solveMs !== undefined) parts.push(`solve ${last.solveMs.toFixed(1)} ms`);
  }
  $("status-line").textContent = parts.join(" · ");
}

function loading(text) {
  const element = $("loading");
  element.hidden = text === null;
  element.textContent = text ?? "";
}

function report(error, context) {
  console.error(context, error);
  toast(`${context}: ${error.message}`, "error");
}

function connectionChanged(ok) {
  connected = ok;
  if (ok) {
    banner(null);
    toast("Connected to the service again.");
    resync();
    return;
  }
  banner("The service cannot be reached; retrying every 2 s. Edits made meanwhile are not saved.");
  watchConnection();
}

async function watchConnection() {
  while (!connected) {
    await sleep(2000);
    try {
      await api.health();
    } catch {
      // still unreachable: the banner stays
    }
  }
}

/** Bring the local state in line with the service (after a reconnect or a refused edit). */
async function resync() {
  try {
    await refreshLists();
    if (!state.session) return;
    const record = await api.session(state.session.id);
    if (record.revision !== state.session.revision) {
      state.session = record;
      history.clear();
      showCurves();
      await showFeedback();
    }
    updateStatus();
  } catch (error) {
    report(error, "The session could not be refreshed");
  }
}

// -- controls ----------------------------------------------------------------------------------------------
function bindControls() {
  $("open-pair").addEventListener("click", openPair);
  $("upload-input").addEventListener("change", (event) => upload(event.target));
  $("target-select").addEventListener("change", (event) => (event.target.dataset.touched = "yes"));
  $("session-select").addEventListener("change", (event) => event.target.value && openSession(event.target.value));
  $("undo-button").addEventListener("click", (event) => undo(event.timeStamp));
  $("cancel-pending").addEventListener("click", () => {
    pending.clear();
    showPending();
  });
  for (const input of document.querySelectorAll('input[name="function"]')) {
    input.addEventListener("change", () => selectFunction(input.value));
  }
  for (const input of document.querySelectorAll('input[name="map"]')) {
    input.addEventListener("change", (event) => {
      state.map = input.value;
      showFeedback(event.timeStamp, "map");
    });
  }
  $("region-radius").addEventListener("change", (event) => {
    if (state.region) setRegion(state.region.center, event.timeStamp);
  });
  $("region-pick").addEventListener("click", () => {
    state.pickingRegion = true;
    showPending();
  });
  $("up-select").addEventListener("change", () => state.ready && orientViews());
  $("reset-view").addEventListener("click", () => state.ready && orientViews());
  $("link-cameras").addEventListener("change", (event) => {
    if (event.target.checked && state.ready) views.target.copyCamera(views.source);
  });
  $("show-curves").addEventListener("change", (event) => {
    for (const side of SIDES) views[side].showCurves(event.target.checked);
  });
  $("texture-input").addEventListener("change", (event) => useTextureImage(event.target));
  $("refine-button").addEventListener("click", refine);
  $("cancel-refine").addEventListener("click", async () => {
    try {
      if (state.refineJob) await api.cancelJob(state.refineJob);
    } catch (error) {
      report(error, "The refinement could not be canceled");
    }
  });
  $("download-c").addEventListener("click", (event) => {
    event.preventDefault();
    if (state.session) downloadLiveMap();
  });
  window.addEventListener("keydown", (event) => {
    if (event.target.closest("input, select, textarea")) return;
    if (event.key === "Escape") {
      pending.clear();
      state.pickingRegion = false;
      showPending();
    } else if ((event.ctrlKey || event.metaKey) && event.key === "z" && state.ready) {
      event.preventDefault();
      undo(performance.now());
    }
  });
}
