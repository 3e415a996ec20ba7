// Downloads: saving what a URL answers, and the links to the files a refinement job wrote. The service names every
// download after its session, converter and revision (Content-Disposition), which wins over a link's own name.

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

/** Download what ``url`` answers, saved under the name the server gives. */
export function saveUrl(url) {
  const link = Object.assign(document.createElement("a"), { href: url, download: "" });
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
