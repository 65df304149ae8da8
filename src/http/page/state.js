// What is on screen, which every part of the page reads, and the one helper they share.

export const $ = (id) => document.getElementById(id);

// What is on screen: the job, the vertices streamed so far, then its document.
export const view = {
  kind: "mesh", // or "solution"
  id: null,
  domain: null, // [x0, x1, y0, y1]
  points: [], // flat x, y, z while the job runs
  doc: null, // the final mesh document
  status: null, // GET /v1/jobs/{id} once finished
  errors: null, // per-triangle error (from the PLY download), by job id
  mode: "flat", // flat | surface | error
  request: null, // what was sent, for the share link and the curl line
  file: null, // a grid file picked or dropped
  abort: null,
};
