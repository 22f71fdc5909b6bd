// Exports panel of the queue and statistics pages: every export one click away, for the roles that
// may export (admins; the panel stays hidden for the others, whom the API refuses anyway). A click queues the
// export as a background job (POST /api/exports/{format}); the panel follows that job (GET /api/jobs/{id}) with
// its progress and, when it is done, a download link to the file the server keeps for a while
// (/api/jobs/{id}/result). "Accepted systems only", "all systems" or a release (its accepted systems as they were
// when it was made, byte for byte the same file whenever asked) applies to every button.

import { getMe, send } from "./api.js";
import { jobProgressText } from "./jobs.js";
import { el, showError } from "./format.js";
// the exports offered ({id, label, format, body, title}), written from the server's registry of export formats
import { EXPORTS } from "./exportlist.js";

const ACTIVE = new Set(["queued", "running"]);
const POLL_MS = 1000;

/** Where a job's state is shown beside its button: progress while it runs, a download link when done. */
function status(job) {
  const parts = [el("span", { class: `chip ${job.state === "failed" ? "bad" : job.state === "done" ? "ok" : ""}` }, job.state)];
  if (ACTIVE.has(job.state)) {
    const bar = el("progress", { max: String(job.total || 1) });
    if (job.total) bar.value = job.done;
    parts.push(bar, el("span", { class: "muted" }, jobProgressText(job)));
  }
  if (job.state === "failed") parts.push(el("span", { class: "bad" }, job.message || "failed"));
  if (job.result_url) {
    const name = (job.result && job.result.filename) || "export.zip";
    const mb = job.result && job.result.bytes ? ` (${(job.result.bytes / 1048576).toFixed(1)} MB)` : "";
    parts.push(el("a", { href: job.result_url, download: name, "data-testid": "export-download" }, `download ${name}${mb}`));
    const empty = (job.result && job.result.empty_splits) || [];
    if (empty.length) parts.push(el("span", { class: "warn" }, `no image in split ${empty.join(", ")}`));
  }
  return parts;
}

class ExportsPanel {
  constructor(root) {
    this.root = root;
    this.scope = el("select", { "data-testid": "export-scope", title: "Which systems every export holds" },
      el("option", { value: "accepted" }, "accepted systems only"), el("option", { value: "all" }, "all systems"));
    this.addReleases();
    this.list = el("ul");
    for (const x of EXPORTS) {
      const button = el("button", { type: "button", "data-testid": `export-${x.id}`, title: x.title }, x.label);
      button.addEventListener("click", () => this.start(x, button));
      const li = el("li", { "data-testid": "export-row", "data-export": x.id }, button,
        el("span", { class: "export-status", "data-testid": `export-status-${x.id}` }));
      this.list.append(li);
    }
    root.replaceChildren(el("h2", { title: "Each export runs as a job; its file is kept on the server for a while (V3D_EXPORT_KEEP_HOURS), then removed" }, "Exports"),
      el("label", { class: "muted" }, "Systems ", this.scope), this.list);
  }

  /** Offer each release (newest first) in the scope select; a page without releases keeps the two scopes. */
  async addReleases() {
    let releases = [];
    try {
      releases = (await send("GET", "/api/releases")).items || [];
    } catch {
      return; // the exports of the database now stay offered
    }
    const group = el("optgroup", { label: "a release (the same bytes whenever asked)" });
    for (const r of [...releases].reverse()) {
      group.append(el("option", { value: `release:${r.name}`, title: `hash ${r.hash}` },
        `release ${r.name} (${r.systems} systems)`));
    }
    if (releases.length) this.scope.append(group);
  }

  /** The body of an export job for the chosen scope: a release by name, or all / accepted systems now. */
  scopeBody() {
    const v = this.scope.value;
    return v.startsWith("release:") ? { release: v.slice("release:".length) } : { all: v === "all" };
  }

  async start(x, button) {
    const cell = this.root.querySelector(`[data-testid="export-status-${x.id}"]`);
    button.disabled = true;
    try {
      const job = await send("POST", `/api/exports/${x.format}`, {
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ ...x.body, ...this.scopeBody() }),
      });
      await this.follow(job, cell);
    } catch (err) {
      showError(`${x.label} export: ${err.message}`);
    } finally {
      button.disabled = false;
    }
  }

  async follow(job, cell) {
    for (;;) {
      cell.replaceChildren(...status(job));
      cell.dataset.state = job.state;
      if (!ACTIVE.has(job.state)) return;
      await new Promise((resolve) => setTimeout(resolve, POLL_MS));
      job = await send("GET", job.url);
    }
  }
}

/** Show the exports panel in `root` (a hidden element) when the person may export. */
export async function mountExports(root) {
  if (!root) return null;
  let me;
  try {
    me = await getMe();
  } catch {
    return null;
  }
  if (me.role !== "admin") return null;
  const panel = new ExportsPanel(root);
  root.hidden = false;
  return panel;
}
