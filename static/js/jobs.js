// Jobs panel of the queue page: background imports, full recomputes and exports (GET /api/jobs), with
// their progress. It polls every 2 s while a job is queued or running and every 5 s otherwise. It shows
// the jobs queued or running and those created since the page opened (finished: their outcome, an
// export's download link, a failure's message); `onFinished(job)` is called once for each of those
// that ends, so the queue can reload what an import or a recompute changed.

import { listJobs } from "./api.js";
import { el } from "./format.js";

const ACTIVE = new Set(["queued", "running"]);
const FAST_MS = 2000;
const SLOW_MS = 5000;
const STAGE_LABEL = {
  read: "reading", games: "games stored", merge: "merging", calibrate: "calibrating", rig: "calibrating with game rigs",
  prior: "calibrating with the learned prior",
  triangulate: "triangulating", recompute: "systems recomputed", export: "games exported", zip: "files zipped",
  predictions: "predictions read (bytes)", store: "frames stored",
};

/** One line saying what a job runs: an import's kind and folder, an export's selection. */
export function jobTitle(job) {
  const p = job.params || {};
  // an upload by its file's name (the server's upload folder says nothing to the person who sent it)
  if (job.kind === "import") return `import ${p.kind || ""} ${p.name || String(p.path || "").split("/").slice(-2).join("/")}`;
  if (job.kind === "export") return `export ${p.format || ""}${p.images === false ? " without images" : ""}${p.all ? " (all systems)" : " (accepted systems)"}`;
  return "full recompute";
}

/** "calibrating 12 / 40" (or the stage alone when its total is unknown). */
export function jobProgressText(job) {
  if (!job.stage) return job.state;
  const stage = STAGE_LABEL[job.stage] || job.stage;
  return job.total ? `${stage} ${job.done} / ${job.total}` : `${stage} ${job.done || ""}`.trim();
}

function row(job) {
  const bar = el("progress", { "data-testid": "job-progress", max: String(job.total || 1) });
  if (job.total) bar.value = job.done; // no value: an indeterminate bar
  const state = el("span", { class: `chip ${job.state === "failed" ? "bad" : job.state === "done" ? "ok" : ""}`, "data-testid": "job-state" }, job.state);
  const parts = [state, el("span", { class: "mono" }, `#${job.id}`), el("span", { "data-testid": "job-title" }, jobTitle(job))];
  if (ACTIVE.has(job.state)) parts.push(bar, el("span", { class: "muted", "data-testid": "job-progress-text" }, jobProgressText(job)));
  if (job.state === "failed" && job.message) parts.push(el("span", { class: "bad", "data-testid": "job-message" }, job.message));
  if (job.result_url) parts.push(el("a", { href: job.result_url, "data-testid": "job-download" }, "download"));
  if (job.attempts > 1 && ACTIVE.has(job.state)) parts.push(el("span", { class: "muted", title: "its first process was stopped; this runner resumed it" }, "resumed"));
  return el("li", { "data-testid": "job", "data-id": String(job.id), "data-state": job.state }, ...parts);
}

export class JobsPanel {
  /** @param {HTMLElement} root the panel (hidden while there is nothing to show) */
  constructor(root, onFinished = () => {}) {
    this.root = root;
    this.list = root.querySelector("ul");
    this.onFinished = onFinished;
    this.baseline = null; // the newest job id when the page opened: later jobs are shown whatever their state
    this.reported = new Set(); // finished jobs already handed to onFinished
    this.poll();
  }

  async poll() {
    let delay = SLOW_MS;
    try {
      const page = await listJobs({ limit: 10 });
      if (this.baseline === null) {
        this.baseline = Math.max(0, ...page.items.filter((j) => !ACTIVE.has(j.state)).map((j) => j.id));
        for (const j of page.items) if (!ACTIVE.has(j.state)) this.reported.add(j.id);
      }
      const items = page.items.filter((j) => ACTIVE.has(j.state) || j.id > this.baseline).slice(0, 6);
      for (const j of items) {
        if (!ACTIVE.has(j.state) && !this.reported.has(j.id)) {
          this.reported.add(j.id);
          this.onFinished(j);
        }
      }
      this.list.replaceChildren(...items.map(row));
      this.root.hidden = items.length === 0;
      if (items.some((j) => ACTIVE.has(j.state))) delay = FAST_MS;
    } catch {
      // not logged in, or the server is restarting: try again later, quietly
    }
    setTimeout(() => this.poll(), delay);
  }
}
