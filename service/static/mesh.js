// Decodes GET /shapes/{id}/mesh (binary form) into typed arrays, plus the lookups the UI needs.

/**
 * Layout: uint32 header length H (little-endian), H bytes of JSON header, then the arrays back to back; the
 * header gives each array's dtype, shape and byte offset from the end of the header.
 * Returns { name, nVertices, vertices: Float32Array(n*3), faces: Uint32Array(f*3), fileIds: Uint32Array(n),
 * fileToInternal: Int32Array (file id -> internal id, -1 if dropped) }.
 */
export function decodeMesh(buffer) {
  const headerLength = new DataView(buffer).getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, headerLength)));
  const start = 4 + headerLength;
  const arrays = {};
  for (const [name, { dtype, shape, offset }] of Object.entries(header.arrays)) {
    const Type = { float32: Float32Array, uint32: Uint32Array }[dtype];
    if (!Type) throw new Error(`mesh payload: unexpected dtype ${dtype} of ${name}`);
    arrays[name] = new Type(buffer, start + offset, shape.reduce((a, b) => a * b, 1));
  }
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
  };
}

/** A map file as written by the service (line j: the source file id for target file vertex j, as
 * ``map_target_to_source.txt``) as internal ids: Int32Array, entry i = source vertex of target vertex i. */
export function pointwiseMap(text, source, target) {
  const lines = text.trim().split("\n");
  const p2p = new Int32Array(target.nVertices);
  for (let i = 0; i < target.nVertices; i++) {
    const vertex = source.fileToInternal[Number(lines[target.fileIds[i]])];
    if (vertex === undefined || vertex < 0) {
      throw new Error(`the map names no source vertex for target vertex ${target.fileIds[i]}`);
    }
    p2p[i] = vertex;
  }
  return p2p;
}
