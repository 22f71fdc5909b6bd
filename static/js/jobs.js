// Jobs panel of the queue page: background imports, full recomputes and exports (GET /api/jobs), with
// their progress, and the last few that finished (those run from the command line too: `v3d import` records
// its job like the server's runner does), each with what it gave in words as the server stored it in its result
// (`result.summary`: "256 systems: 144 with a 3D ball; 87 views without a camera", with links to those systems
// in the queue). It polls every 2 s while a job is queued or running and every 5 s otherwise; `onFinished(job)` is
// called once for each job that ends while the page is open, so the queue can reload what an import or a
// recompute changed.

import { listJobs } from "./api.js";
import { el, fmtBytes, fmtWhen } from "./format.js";
import { stateQuery } from "./queuestate.js";

const ACTIVE = new Set(["queued", "running"]);
const FAST_MS = 2000;
const SLOW_MS = 5000;
/** How many finished jobs the panel keeps showing (newest first), beside the queued and running ones. */
export const RECENT_FINISHED = 5;
const STAGE_LABEL = {
  read: "reading", games: "games stored", merge: "merging", calibrate: "calibrating", rig: "calibrating with game rigs",
  prior: "calibrating with the learned prior", predictions: "reading the predictions",
  triangulate: "triangulating", recompute: "systems recomputed", export: "games exported", zip: "files zipped",
  store: "frames stored", tables: "rows read", files: "files copied",
};
/** Stages whose count is bytes of a file, not items: shown as the share read. */
const BYTE_STAGES = new Set(["predictions"]);

/** One line saying what a job runs: an import's kind and folder, an export's selection. */
export function jobTitle(job) {
  const p = job.params || {};
  // an upload by its file's name (the server's upload folder says nothing to the person who sent it)
  if (job.kind === "import") return `import ${p.kind || ""} ${p.name || String(p.path || "").split("/").slice(-2).join("/")}`;
  if (job.kind === "export") return `export ${p.format || ""}${p.images === false ? " without images" : ""}${p.release ? ` of release ${p.release}` : p.all ? " (all systems)" : " (accepted systems)"}`;
  if (job.kind === "backup") return `backup${p.local_files === false ? " without this machine's dataset files" : ""}`;
  return "full recompute";
}

/** Who started it: the user who queued it through the API, or the command line (a job `v3d import` ran). */
export function jobAuthor(job) {
  const p = job.params || {};
  if (p.actor) return p.actor;
  return job.kind === "export" ? "" : "command line";
}

/** "calibrating 12 / 40", "reading the predictions 45 %" (a file read by bytes: its rows are counted in the
 * result), or the stage alone when its total is unknown. */
export function jobProgressText(job) {
  if (!job.stage) return job.state;
  const stage = STAGE_LABEL[job.stage] || job.stage;
  if (job.total && BYTE_STAGES.has(job.stage)) return `${stage} ${Math.floor((100 * job.done) / job.total)} %`;
  return job.total ? `${stage} ${job.done} / ${job.total}` : `${stage} ${job.done || ""}`.trim();
}

/** The progress bar of a running job: indeterminate (no value) while its total is unknown or its count is full
 * (a running job is never drawn as a full bar: it has its last writes to make). */
export function progressBar(job, attrs = {}) {
  const bar = el("progress", { max: String(job.total || 1), ...attrs });
  if (job.total && job.done < job.total) bar.value = job.done;
  return bar;
}

/** What a finished job gave, in the words the server stored, its links to the queue's filters in place. */
function summaryNode(job) {
  const s = job.result && job.result.summary;
  if (!s || !s.words) return null;
  const node = el("span", { class: "job-summary", "data-testid": "job-summary" });
  let rest = s.words;
  for (const link of s.links || []) {
    const at = rest.indexOf(link.text);
    if (at < 0) continue;
    node.append(rest.slice(0, at), el("a", { href: `/${stateQuery(link.query || {}, { withPage: false })}`,
      "data-testid": "job-summary-link", title: "these systems in the queue" }, link.text));
    rest = rest.slice(at + link.text.length);
  }
  node.append(rest);
  return node;
}

function row(job) {
  const state = el("span", { class: `chip ${job.state === "failed" ? "bad" : job.state === "done" ? "ok" : ""}`, "data-testid": "job-state" }, job.state);
  const parts = [state, el("span", { class: "mono" }, `#${job.id}`), el("span", { "data-testid": "job-title" }, jobTitle(job))];
  if (ACTIVE.has(job.state)) {
    parts.push(progressBar(job, { "data-testid": "job-progress" }),
      el("span", { class: "muted", "data-testid": "job-progress-text" }, jobProgressText(job)));
  } else {
    const summary = summaryNode(job);
    if (summary) parts.push(summary);
  }
  if (job.state === "failed" && job.message) parts.push(el("span", { class: "bad", "data-testid": "job-message" }, job.message));
  if (job.result_url) {
    const size = job.result && job.result.bytes ? ` (${fmtBytes(job.result.bytes)})` : "";
    parts.push(el("a", { href: job.result_url, "data-testid": "job-download" }, `download${size}`));
  }
  if (job.attempts > 1 && ACTIVE.has(job.state)) parts.push(el("span", { class: "muted", title: "its first process was stopped; this runner resumed it" }, "resumed"));
  const who = jobAuthor(job);
  const when = fmtWhen(job.finished_at || job.created_at);
  parts.push(el("span", { class: "muted", "data-testid": "job-when", title: when.title },
    `${who ? `${who}, ` : ""}${ACTIVE.has(job.state) ? "started" : "finished"} ${when.text}`));
  return el("li", { "data-testid": "job", "data-id": String(job.id), "data-state": job.state }, ...parts);
}

export class JobsPanel {
  /** @param {HTMLElement} root the panel (hidden while there is nothing to show) */
  constructor(root, onFinished = () => {}) {
    this.root = root;
    this.list = root.querySelector("ul");
    this.onFinished = onFinished;
    this.reported = null; // finished jobs already handed to onFinished (those finished before the page opened too)
    this.poll();
  }

  /** Show the job just queued at once (the next poll redraws the list): the words that point at the panel must
   * find it there, not an empty page until the next poll. */
  show(job) {
    if (!this.list.querySelector(`[data-testid=job][data-id="${job.id}"]`)) this.list.prepend(row(job));
    this.root.hidden = false;
  }

  async poll() {
    let delay = SLOW_MS;
    try {
      const page = await listJobs({ limit: 20 }, { background: true }); // a poll: never the page's work (busy.js)
      if (this.reported === null) this.reported = new Set(page.items.filter((j) => !ACTIVE.has(j.state)).map((j) => j.id));
      const active = page.items.filter((j) => ACTIVE.has(j.state));
      const finished = page.items.filter((j) => !ACTIVE.has(j.state)).slice(0, RECENT_FINISHED);
      for (const j of page.items) {
        if (!ACTIVE.has(j.state) && !this.reported.has(j.id)) {
          this.reported.add(j.id);
          this.onFinished(j);
        }
      }
      const items = [...active, ...finished];
      this.list.replaceChildren(...items.map(row));
      this.root.hidden = items.length === 0;
      if (active.length) delay = FAST_MS;
    } catch {
      // not logged in, or the server is restarting: try again later, quietly
    }
    setTimeout(() => this.poll(), delay);
  }
}
