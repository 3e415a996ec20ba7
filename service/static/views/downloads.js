// Downloads: a matrix made into .npy in the browser (what numpy.load reads), saving a Blob under a name, and the
// links to the files a refinement job wrote.

const JOB_FILE_ORDER = [
  "C_source_to_target.npy",
  "C_target_to_source.npy",
  "map_target_to_source.txt",
  "map_source_to_target.txt",
  "p2p_target_to_source.npy",
  "p2p_source_to_target.npy",
  "maps.mat",
  "target_textured.obj",
  "target_textured.zip",
];

/** A rows x cols float64 matrix (array of arrays) as a NumPy .npy file (format 1.0, C order). */
export function npyBlob(matrix) {
  const rows = matrix.length;
  const cols = rows ? matrix[0].length : 0;
  let header = `{'descr': '<f8', 'fortran_order': False, 'shape': (${rows}, ${cols}), }`;
  const unpadded = 10 + header.length + 1; // magic (6) + version (2) + length (2) + header + newline
  header += " ".repeat((64 - (unpadded % 64)) % 64) + "\n";
  const preamble = new Uint8Array(10);
  preamble.set([0x93, ...new TextEncoder().encode("NUMPY"), 1, 0]);
  new DataView(preamble.buffer).setUint16(8, header.length, true);
  const data = new Float64Array(rows * cols);
  matrix.forEach((row, i) => data.set(row, i * cols));
  return new Blob([preamble, header, data], { type: "application/octet-stream" });
}

export function saveBlob(blob, name) {
  const url = URL.createObjectURL(blob);
  saveUrl(url, name);
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

/** Download what ``url`` answers, saved as ``name`` (empty: the name the server gives). */
export function saveUrl(url, name = "") {
  const link = Object.assign(document.createElement("a"), { href: url, download: name });
  document.body.append(link);
  link.click();
  link.remove();
}

/** Replace the job-file items of ``list`` by one download link per file (links: name -> URL). */
export function listJobFiles(list, links) {
  list.querySelectorAll("li.job-file").forEach((item) => item.remove());
  const rank = (name) => (JOB_FILE_ORDER.includes(name) ? JOB_FILE_ORDER.indexOf(name) : JOB_FILE_ORDER.length);
  for (const name of Object.keys(links).sort((a, b) => rank(a) - rank(b))) {
    const link = Object.assign(document.createElement("a"), { href: links[name], download: name, textContent: name });
    const item = Object.assign(document.createElement("li"), { className: "job-file" });
    item.append(link);
    list.append(item);
  }
}
