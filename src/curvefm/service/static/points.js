// Where a shape's vertices are, by file id, for what names vertices the viewport may not draw. A big shape is
// drawn as a display copy (GET /shapes/{id}/mesh) whose vertices are some of its vertices, while curve paths, the
// weakest vertex and a pointwise map's images name any vertex. A shape drawn whole answers from its mesh; a
// display copy asks the service (POST /shapes/{id}/points) once per vertex and remembers.
import { api } from "./api.js";

export class VertexPoints {
  /** mesh: the decoded mesh payload of shape ``shapeId`` (mesh.js). */
  constructor(shapeId, mesh) {
    this.shapeId = shapeId;
    this.mesh = mesh;
    this.known = new Map(); // file id -> { position: [x, y, z], row: the drawn vertex nearest to it }
    this.asked = new Map(); // file id -> the request that will place it
  }

  /** Whether every one of ``fileIds`` can be placed now. */
  has(fileIds) {
    return fileIds.every((id) => this.drawnRow(id) >= 0 || this.known.has(id));
  }

  /** The row of a drawn vertex, -1 for a vertex the mesh payload does not draw. */
  drawnRow(fileId) {
    return this.mesh.fileToInternal[fileId] ?? -1;
  }

  /** Ask the service where the ``fileIds`` not known yet are (one request); resolves once all are known. */
  async load(fileIds) {
    const waiting = new Set();
    const missing = [];
    for (const id of new Set(fileIds)) {
      if (this.drawnRow(id) >= 0 || this.known.has(id)) continue;
      if (this.asked.has(id)) waiting.add(this.asked.get(id));
      else missing.push(id);
    }
    if (missing.length) {
      const request = this.fetch(missing);
      for (const id of missing) this.asked.set(id, request);
      waiting.add(request);
    }
    await Promise.all(waiting);
  }

  async fetch(fileIds) {
    try {
      const { positions, nearest_row: rows } = await api.points(this.shapeId, fileIds);
      fileIds.forEach((id, i) => {
        this.known.set(id, { position: positions.subarray(3 * i, 3 * i + 3), row: rows[i] });
      });
    } finally {
      for (const id of fileIds) this.asked.delete(id);
    }
  }

  /** The drawn vertex nearest to each file id (itself when it is drawn): Int32Array, -1 where not known. */
  rows(fileIds) {
    return Int32Array.from(fileIds, (id) => {
      const row = this.drawnRow(id);
      return row >= 0 ? row : (this.known.get(id)?.row ?? -1);
    });
  }

  /** Positions of a path of file ids (placed ones: see has), Float32Array n x 3 in the mesh's frame. */
  path(fileIds) {
    const { vertices } = this.mesh;
    const out = new Float32Array(3 * fileIds.length);
    fileIds.forEach((id, i) => {
      const row = this.drawnRow(id);
      out.set(row >= 0 ? vertices.subarray(3 * row, 3 * row + 3) : this.known.get(id).position, 3 * i);
    });
    return out;
  }
}
