// Curves: the clicks of the curve being entered, the list of the session's curves, and undo.

const PALETTE = [
  "#e6194b", "#1f78ff", "#2ca02c", "#ff7f0e", "#9b30ff", "#00a6a6", "#d62fb4", "#8c564b", "#bcbd22", "#111111",
];

/** A curve keeps its colour for its whole life: the colour follows the number in its id (c1, c2, ...). */
export function curveColor(curveId) {
  const number = Number.parseInt(String(curveId).replace(/\D/g, ""), 10) || 1;
  return PALETTE[(number - 1) % PALETTE.length];
}

/**
 * The clicks of a curve pair being entered, in internal vertex ids per side ("source", "target"). A plain
 * click adds a point, and a plain click after the first ends that side; Shift+click adds a waypoint and goes
 * on. Clicking a side that is already complete starts it over. Sides may be entered in either order.
 */
export class PendingCurve {
  constructor() {
    this.clear();
  }

  clear() {
    this.points = { source: [], target: [] };
    this.closed = { source: false, target: false };
  }

  click(side, vertex, waypoint) {
    if (this.closed[side]) {
      this.points[side] = [];
      this.closed[side] = false;
    }
    this.points[side].push(vertex);
    if (!waypoint && this.points[side].length >= 2) this.closed[side] = true;
  }

  get complete() {
    return this.closed.source && this.closed.target;
  }

  get empty() {
    return this.points.source.length === 0 && this.points.target.length === 0;
  }

  /** What to do next, for the hint line. */
  hint() {
    for (const side of ["source", "target"]) {
      const count = this.points[side].length;
      if (this.closed[side]) continue;
      if (count === 0 && this.empty) {
        return "Click the start of a curve on the source (then its end), then on the target.";
      }
      if (count === 0) return `Now click the start on the ${side}, then its end.`;
      return `Click the end on the ${side}; Shift+click adds a waypoint (${count} so far).`;
    }
    return "";
  }
}

/**
 * Edits that can be undone, newest last. ``undo(ops)`` reverses the newest through
 * ``ops = { add(spec), remove(curveId), replace(curveId, spec) }`` (each resolves to the service's edit).
 */
export class History {
  constructor() {
    this.entries = [];
  }

  get size() {
    return this.entries.length;
  }

  clear() {
    this.entries = [];
  }

  added(curve) {
    this.entries.push({ kind: "add", curveId: curve.id });
  }

  removed(curve) {
    this.entries.push({ kind: "remove", curveId: curve.id, spec: curve.spec });
  }

  replaced(previous) {
    this.entries.push({ kind: "replace", curveId: previous.id, spec: previous.spec });
  }

  /** Reverse the newest edit and resolve to the service's answer. When the service refuses, the entry
   * stays, so it can be tried again. A re-added curve gets a new id; older entries follow it. */
  async undo(ops) {
    const entry = this.entries.at(-1);
    let edit;
    if (entry.kind === "add") {
      edit = await ops.remove(entry.curveId);
    } else if (entry.kind === "remove") {
      edit = await ops.add(entry.spec);
      for (const older of this.entries) if (older.curveId === entry.curveId) older.curveId = edit.curve.id;
    } else {
      edit = await ops.replace(entry.curveId, entry.spec);
    }
    this.entries.pop();
    return edit;
  }
}

/**
 * The list of curves: colour, id, tracer, path lengths, and buttons. ``actions``: select(id),
 * retrace(id, clickTime), remove(id, clickTime). The selected curve is drawn thicker in the viewports.
 */
export function renderCurveList(list, curves, selectedId, actions) {
  list.replaceChildren(
    ...curves.map((curve) => {
      const item = document.createElement("li");
      item.dataset.curveId = curve.id;
      item.classList.toggle("selected", curve.id === selectedId);
      item.title =
        `${curve.id}: traced by ${curve.tracer}, ${curve.path_source.length} vertices on the source and ` +
        `${curve.path_target.length} on the target. Click to select (drawn thicker).`;
      const swatch = document.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = curveColor(curve.id);
      const label = document.createElement("span");
      label.className = "curve-label";
      label.textContent = `${curve.id} · ${curve.tracer} · ${curve.path_source.length}/${curve.path_target.length} v`;
      const retrace = button("↻", "re-trace with the tracer chosen above", "retrace");
      item.append(swatch, label, retrace, button("✕", "delete", "delete"));
      item.addEventListener("click", (event) => {
        const action = event.target.closest("button")?.dataset.action;
        if (action === "retrace") actions.retrace(curve.id, event.timeStamp);
        else if (action === "delete") actions.remove(curve.id, event.timeStamp);
        else actions.select(curve.id === selectedId ? null : curve.id);
      });
      return item;
    }),
  );
}

function button(text, title, action) {
  const element = document.createElement("button");
  element.type = "button";
  element.className = "icon";
  element.textContent = text;
  element.title = title;
  element.setAttribute("aria-label", title);
  element.dataset.action = action;
  return element;
}
