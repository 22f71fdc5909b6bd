// Exports panel of the queue and statistics pages: every export one click away, for the roles that
// may export (admins; the panel stays hidden for the others, whom the API refuses anyway). A click queues the
// export as a background job (POST /api/exports/{format}); the panel follows that job (GET /api/jobs/{id}) with
// its progress and, when it is done, a download link to the file the server keeps for a while
// (/api/jobs/{id}/result). "Accepted systems only", "all systems" or a release (its accepted systems as they were
// when it was made, byte for byte the same file whenever asked) applies to every button. On the Releases page the
// panel offers the releases alone (`mountExports(root, { releasesOnly: true })`), the newest chosen.

import { getMe, send } from "./api.js";
import { whileWorking } from "./busy.js";
import { jobProgressText, progressBar } from "./jobs.js";
import { el, fmtBytes, showError } from "./format.js";
// the exports offered ({id, label, format, body, title}), written from the server's registry of export formats
import { EXPORTS } from "./exportlist.js";

const ACTIVE = new Set(["queued", "running"]);
const POLL_MS = 1000;

/** Where a job's state is shown beside its button: progress while it runs, a download link when done. */
function status(job) {
  const parts = [el("span", { class: `chip ${job.state === "failed" ? "bad" : job.state === "done" ? "ok" : ""}` }, job.state)];
  if (ACTIVE.has(job.state)) {
    parts.push(progressBar(job), el("span", { class: "muted" }, jobProgressText(job)));
  }
  if (job.state === "failed") parts.push(el("span", { class: "bad" }, job.message || "failed"));
  // an export that held nothing says why instead of offering an empty file
  if (job.state === "done" && job.result && job.result.nothing) {
    parts.push(el("span", { class: "warn", "data-testid": "export-nothing" }, job.result.nothing));
  }
  if (job.result_url) {
    const name = (job.result && job.result.filename) || "export.zip";
    const size = job.result && job.result.bytes ? ` (${fmtBytes(job.result.bytes)})` : "";
    parts.push(el("a", { href: job.result_url, download: name, "data-testid": "export-download" }, `download ${name}${size}`));
    const empty = (job.result && job.result.empty_splits) || [];
    if (empty.length) parts.push(el("span", { class: "warn" }, `no image in split ${empty.join(", ")}`));
  }
  return parts;
}

class ExportsPanel {
  constructor(root, { releasesOnly = false } = {}) {
    this.root = root;
    this.releasesOnly = releasesOnly;
    this.scope = el("select", { "data-testid": "export-scope", title: "Which systems every export holds" });
    // a finished job's link is of the scope it was asked with: another scope chosen, it goes
    this.scope.addEventListener("change", () => this.forgetOtherScopes());
    this.ready = this.addReleases();
    this.list = el("ul");
    for (const x of EXPORTS) {
      // disabled until the releases are read: a click before would export with no scope chosen yet (on the
      // Releases page, the database now instead of the release the page is about to choose)
      const button = el("button", { type: "button", "data-testid": `export-${x.id}`, title: x.title, disabled: true },
        x.label);
      button.addEventListener("click", () => this.start(x, button));
      const li = el("li", { "data-testid": "export-row", "data-export": x.id }, button,
        el("span", { class: "export-status", "data-testid": `export-status-${x.id}` }));
      this.list.append(li);
    }
    root.replaceChildren(el("h2", { title: "Each export runs as a job; its file is kept on the server for a while (V3D_EXPORT_KEEP_HOURS), then removed" }, "Exports"),
      el("label", { class: "muted" }, "Systems ", this.scope), this.list);
  }

  /** Offer each release (newest first) in the scope select, after the two scopes of the database now (on the
   * Releases page the releases alone, the newest chosen); called again when a release is made. */
  async addReleases() {
    let releases = [];
    try {
      releases = (await send("GET", "/api/releases")).items || [];
    } catch {
      releases = []; // the exports of the database now stay offered
    }
    const chosen = this.scope.value;
    const options = this.releasesOnly ? [] : [el("option", { value: "accepted" }, "accepted systems only"),
      el("option", { value: "all" }, "all systems")];
    const group = el("optgroup", { label: "a release (the same bytes whenever asked)" });
    for (const r of [...releases].reverse()) {
      group.append(el("option", { value: `release:${r.name}`, title: `hash ${r.hash}` },
        `release ${r.name} (${r.systems} system${r.systems === 1 ? "" : "s"})`));
    }
    this.scope.replaceChildren(...options, ...(releases.length ? [group] : []));
    if (this.releasesOnly) this.scope.value = releases.length ? `release:${releases[releases.length - 1].name}` : "";
    else if (chosen) this.scope.value = chosen;
    for (const b of this.list.querySelectorAll("button")) b.disabled = this.releasesOnly && !releases.length;
    this.forgetOtherScopes();
  }

  /** Clear every export's state that was asked for another scope than the one chosen now, so that a download link
   * beside "release v1.1" is never the file of v1.0 (a new release chosen, or the person's own choice). */
  forgetOtherScopes() {
    for (const cell of this.list?.querySelectorAll(".export-status[data-scope]") || []) {
      if (cell.dataset.scope === this.scope.value) continue;
      cell.replaceChildren();
      delete cell.dataset.scope;
      delete cell.dataset.state;
    }
  }

  /** The body of an export job for the chosen scope: a release by name, or all / accepted systems now. */
  scopeBody() {
    const v = this.scope.value;
    return v.startsWith("release:") ? { release: v.slice("release:".length) } : { all: v === "all" };
  }

  async start(x, button) {
    const cell = this.root.querySelector(`[data-testid="export-status-${x.id}"]`);
    cell.dataset.scope = this.scope.value;
    button.disabled = true;
    try {
      const job = await send("POST", `/api/exports/${x.format}`, {
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ ...x.body, ...this.scopeBody() }),
      });
      await whileWorking("job", this.follow(job, cell)); // the page's work until the job ends (busy.js)
    } catch (err) {
      showError(`${x.label} export: ${err.message}`);
    } finally {
      button.disabled = false;
    }
  }

  async follow(job, cell) {
    const scope = cell.dataset.scope;
    for (;;) {
      if (cell.dataset.scope !== scope) return; // another scope chosen meanwhile: this job's state is not shown
      cell.replaceChildren(...status(job));
      cell.dataset.state = job.state;
      if (!ACTIVE.has(job.state)) return;
      await new Promise((resolve) => setTimeout(resolve, POLL_MS));
      job = await send("GET", job.url);
    }
  }
}

/** Show the exports panel in `root` (a hidden element) when the person may export; `options.releasesOnly`: the
 * releases alone as scopes (the Releases page). */
export async function mountExports(root, options = {}) {
  if (!root) return null;
  let me;
  try {
    me = await getMe();
  } catch {
    return null;
  }
  if (me.role !== "admin") return null;
  const panel = new ExportsPanel(root, options);
  root.hidden = false;
  return panel;
}
