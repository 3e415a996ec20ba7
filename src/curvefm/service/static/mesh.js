// Decodes GET /shapes/{id}/mesh (binary form) into typed arrays, plus the lookups the UI needs.

/**
 * The service's binary layout (meshes, points): uint32 header length H (little-endian), H bytes of JSON header,
 * then the arrays back to back; the header gives each array's dtype, shape and byte offset from the end of the
 * header. Returns { header, arrays: { name: Float32Array | Uint32Array } }.
 */
export function decodeArrays(buffer) {
  const headerLength = new DataView(buffer).getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, headerLength)));
  const start = 4 + headerLength;
  const arrays = {};
  for (const [name, { dtype, shape, offset }] of Object.entries(header.arrays)) {
    const Type = { float32: Float32Array, uint32: Uint32Array }[dtype];
    if (!Type) throw new Error(`payload: unexpected dtype ${dtype} of ${name}`);
    arrays[name] = new Type(buffer, start + offset, shape.reduce((a, b) => a * b, 1));
  }
  return { header, arrays };
}

/**
 * A mesh payload: { name, nVertices (drawn), vertices: Float32Array(n*3), faces: Uint32Array(f*3), fileIds:
 * Uint32Array(n), fileToInternal: Int32Array (file id -> drawn row, -1 if not drawn), texcoords, winding (see
 * outwardWinding), displayCopy (a big shape's coarser copy, whose rows are some of its vertices), shapeVertices
 * (the shape's vertex count) }. The UI calls a drawn row a vertex: it speaks file ids to the service.
 */
export function decodeMesh(buffer) {
  const { header, arrays } = decodeArrays(buffer);
  const { vertices, faces, file_ids: fileIds } = arrays;
  let maxFileId = -1;
  for (const id of fileIds) if (id > maxFileId) maxFileId = id;
  const fileToInternal = new Int32Array(maxFileId + 1).fill(-1);
  fileIds.forEach((fileId, internal) => {
    fileToInternal[fileId] = internal;
  });
  return {
    name: header.name,
    nVertices: fileIds.length,
    vertices,
    faces,
    fileIds,
    fileToInternal,
    texcoords: arrays.texcoords,
    winding: outwardWinding(vertices, faces, fileIds.length),
    displayCopy: header.display_copy,
    shapeVertices: header.shape_vertices,
  };
}

/** How the faces are wound seen from outside: 1 when every face turns counter-clockwise seen from outside, -1 when
 * every face turns the other way (inside out), 0 when that cannot be told (an edge run twice the same way:
 * non-manifold or inconsistently wound; a part that is open, with holes whose vector area is over
 * ``maxOpening`` of its area, or flat): then both sides of a face may be seen. Small holes (TOSCA's cats and
 * dogs: under 0.1%) do not count: through them one sees what is behind the shape. */
export function outwardWinding(vertices, faces, nVertices, maxOpening = 0.01) {
  const edges = directedEdges(faces, nVertices);
  if (!consistentlyWound(edges, nVertices)) return 0;
  const { measures, count } = partMeasures(vertices, faces, connectedParts(edges, nVertices));
  let sign = 0;
  for (let part = 0; part < count; part++) {
    const [volume, area, ax, ay, az] = measures.slice(5 * part, 5 * part + 5);
    if (Math.hypot(ax, ay, az) > maxOpening * area || volume === 0) return 0;
    if (sign !== 0 && Math.sign(volume) !== sign) return 0;
    sign = Math.sign(volume);
  }
  return sign;
}

/** The faces' directed edges (each face runs a -> b -> c -> a) by tail: heads[start[v] .. start[v + 1]) are where
 * the edges from v go. */
function directedEdges(faces, nVertices) {
  const start = new Uint32Array(nVertices + 1);
  for (let i = 0; i < faces.length; i++) start[faces[i] + 1] += 1;
  for (let v = 0; v < nVertices; v++) start[v + 1] += start[v];
  const next = start.slice(0, nVertices);
  const heads = new Uint32Array(faces.length);
  for (let f = 0; f < faces.length; f += 3) {
    heads[next[faces[f]]++] = faces[f + 1];
    heads[next[faces[f + 1]]++] = faces[f + 2];
    heads[next[faces[f + 2]]++] = faces[f];
  }
  return { start, heads };
}

/** Whether no directed edge occurs twice: faces that share an edge run it in opposite directions, and no edge
 * has more than two faces. */
function consistentlyWound({ start, heads }, nVertices) {
  for (let v = 0; v < nVertices; v++) {
    for (let i = start[v]; i < start[v + 1]; i++) {
      for (let j = i + 1; j < start[v + 1]; j++) if (heads[i] === heads[j]) return false;
    }
  }
  return true;
}

/** The connected part of each vertex: { part: Int32Array(n), count }. Following edges forward reaches the whole
 * part, as every edge lies on its face's cycle. */
function connectedParts({ start, heads }, nVertices) {
  const part = new Int32Array(nVertices).fill(-1);
  const stack = new Int32Array(nVertices);
  let count = 0;
  for (let seed = 0; seed < nVertices; seed++) {
    if (part[seed] >= 0) continue;
    part[seed] = count;
    let top = 0;
    stack[top++] = seed;
    while (top > 0) {
      const v = stack[--top];
      for (let i = start[v]; i < start[v + 1]; i++) {
        if (part[heads[i]] < 0) {
          part[heads[i]] = count;
          stack[top++] = heads[i];
        }
      }
    }
    count += 1;
  }
  return { part, count };
}

/** Per connected part, 5 numbers: the signed volume it encloses (times 6), its area and its vector area (x, y,
 * z) (times 2). */
function partMeasures(vertices, faces, { part, count }) {
  const measures = new Float64Array(5 * count);
  const v = vertices;
  for (let f = 0; f < faces.length; f += 3) {
    const a = 3 * faces[f];
    const b = 3 * faces[f + 1];
    const c = 3 * faces[f + 2];
    const ux = v[b] - v[a];
    const uy = v[b + 1] - v[a + 1];
    const uz = v[b + 2] - v[a + 2];
    const wx = v[c] - v[a];
    const wy = v[c + 1] - v[a + 1];
    const wz = v[c + 2] - v[a + 2];
    const nx = uy * wz - uz * wy; // twice the face's vector area
    const ny = uz * wx - ux * wz;
    const nz = ux * wy - uy * wx;
    const m = 5 * part[faces[f]];
    measures[m] += v[a] * nx + v[a + 1] * ny + v[a + 2] * nz;
    measures[m + 1] += Math.sqrt(nx * nx + ny * ny + nz * nz);
    measures[m + 2] += nx;
    measures[m + 3] += ny;
    measures[m + 4] += nz;
  }
  return { measures, count };
}

/** A map file as written by the service (line j: the source file id for target file vertex j, as
 * ``map_target_to_source.txt``) read at the drawn target vertices: Uint32Array, entry i = the source file id of
 * target vertex i. */
export function mapImages(text, target) {
  const lines = text.trim().split("\n");
  const images = new Uint32Array(target.nVertices);
  for (let i = 0; i < target.nVertices; i++) {
    const image = Number(lines[target.fileIds[i]] ?? Number.NaN);
    if (!Number.isInteger(image) || image < 0) {
      throw new Error(`the map names no source vertex for target vertex ${target.fileIds[i]}`);
    }
    images[i] = image;
  }
  return images;
}
