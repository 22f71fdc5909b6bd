// The team's loop on the queue page: the caller's **To fix** count (systems marked needs fix and returned to them)
// and, for reviewers, **To re-review** (systems they returned that came back fixed), each a link to that part of
// the queue (GET /api/handoffs/mine); and, for admins, the Import panel: a zip uploaded with its progress bar
// (XMLHttpRequest's upload progress), then followed as a job by the Jobs panel (jobs.js), titled by the file's name.

import { getMe, send, writeHeaders } from "./api.js";
import { whileWorking } from "./busy.js";
import { el, fmtBytes, showError } from "./format.js";
import { stateQuery } from "./queuestate.js";

/** The link to a part of the queue assigned to the caller (`status`: the review status, "" for any). */
function queueLink(status) {
  return `/${stateQuery({ assignee: "me", status, sort: "" }, { withPage: false })}`;
}

/** Fill `root` (in the top bar) with the counts; shown even when they are 0. */
export async function mountWorkCounts(root) {
  if (!root) return;
  let me;
  let work;
  try {
    [me, work] = await Promise.all([getMe(), send("GET", "/api/handoffs/mine")]);
  } catch {
    return; // logged out: the page goes to the login anyway
  }
  const toFix = el("a", { class: `work-count${work.to_fix ? " due" : ""}`, href: queueLink(""), "data-testid": "to-fix-count",
    title: "Systems a reviewer marked needs fix and returned to you (the list: every system assigned to you; send each back as fixed from its page)" },
  "To fix ", el("b", {}, String(work.to_fix)));
  const parts = [toFix];
  if (me.role !== "annotator") {
    parts.push(el("a", { class: `work-count${work.to_re_review ? " due" : ""}`, href: queueLink("fixed"), "data-testid": "to-re-review-count",
      title: "Systems you returned that came back fixed: decide them again" },
    "To re-review ", el("b", {}, String(work.to_re_review))));
  }
  root.replaceChildren(...parts);
  root.hidden = false;
}

const KINDS = [
  ["soccernet-v3", "SoccerNet-v3 (Labels-v3.json + Frames-v3.zip)"],
  ["soccernet-v3d", "SoccerNet-v3D (Labels-v3D.json)"],
  ["sn-calibration", "SoccerNet-calibration"],
  ["issia", "ISSIA"],
  ["predictions", "A ball detector's predictions (CSV, YOLO txt or COCO results, zipped)"],
];

/** Upload `file` as an import of `kind` with XMLHttpRequest (fetch reports no upload progress): `onProgress(sent,
 * total)` while it uploads; resolves to the queued job. */
export async function uploadImport(file, kind, onProgress, merge = null) {
  const form = new FormData();
  form.append("kind", kind);
  if (merge) form.append("merge", merge);
  form.append("file", file, file.name);
  const headers = await writeHeaders();
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", "/api/imports");
    xhr.setRequestHeader("Accept", "application/json");
    for (const [k, v] of Object.entries(headers)) xhr.setRequestHeader(k, v);
    xhr.upload.addEventListener("progress", (e) => onProgress(e.loaded, e.lengthComputable ? e.total : file.size));
    xhr.addEventListener("load", () => {
      let body = null;
      try {
        body = JSON.parse(xhr.responseText);
      } catch {
        body = null;
      }
      if (xhr.status === 202) resolve(body);
      else {
        const detail = body && typeof body.detail === "string" ? body.detail : `upload refused (HTTP ${xhr.status})`;
        const err = new Error(body && body.field ? `${detail} (${body.field})` : detail);
        err.status = xhr.status;
        err.body = body;
        reject(err);
      }
    });
    xhr.addEventListener("error", () => reject(new Error("network error while uploading")));
    xhr.send(form);
  });
}

/** Where the Jobs panel is from the Import panel `root`: "above" or "below" as the page lays them out. */
function jobsPlace(root) {
  const jobs = document.querySelector("[data-testid=jobs]");
  if (!jobs || jobs.hidden) return "on the queue page";
  return jobs.compareDocumentPosition(root) & Node.DOCUMENT_POSITION_FOLLOWING ? "above" : "below";
}

/** Follow the queued import `job` until it ends, then say in `text` what it gave (the server's words: a
 * labels-only dataset says it has no images) or why it failed. */
async function followImport(job, name, text) {
  for (;;) {
    await new Promise((resolve) => setTimeout(resolve, 1500));
    try {
      job = await send("GET", job.url);
    } catch {
      continue; // the server restarting: ask again
    }
    if (job.state === "done") {
      const words = job.result && job.result.summary && job.result.summary.words;
      text.textContent = `${name} imported (job #${job.id}): ${words || "done"}`;
      return;
    }
    if (job.state === "failed") {
      text.textContent = `${name} not imported (job #${job.id}): ${job.message || "failed"}`;
      return;
    }
  }
}

/** The Import panel in `root` (hidden unless the caller is an admin); `onQueued(job)` once a job is queued. */
export async function mountImport(root, onQueued = () => {}) {
  if (!root) return;
  let me;
  try {
    me = await getMe();
  } catch {
    return;
  }
  if (me.role !== "admin") return;
  const file = el("input", { type: "file", accept: ".zip,application/zip", "data-testid": "import-file", "aria-label": "dataset zip" });
  const kind = el("select", { "data-testid": "import-kind", "aria-label": "dataset kind" },
    ...KINDS.map(([value, label]) => el("option", { value }, label)));
  const start = el("button", { type: "button", "data-testid": "import-start" }, "Import");
  const bar = el("progress", { "data-testid": "import-upload-progress", max: "1", value: "0", hidden: true });
  const text = el("span", { class: "muted", "data-testid": "import-upload-text" });
  // a dataset whose games are stored already: the server names them and the ways to merge; the person chooses one
  const merge = el("div", { class: "import-merge", "data-testid": "import-merge", role: "group", "aria-label": "merge with the stored games", hidden: true });
  const offerMerge = (chosen, err) => {
    const modes = err.body.current.merge_modes;
    merge.replaceChildren(
      el("span", { "data-testid": "import-merge-text" }, `${chosen.name}: ${err.message}. Import it again, merged:`),
      ...Object.entries(modes).map(([mode, means]) => el("button", {
        type: "button", "data-testid": "import-merge-mode", "data-mode": mode, title: means,
        onclick: () => { merge.hidden = true; send(chosen, mode); },
      }, `${mode.replace("-", " ")}`)),
      el("button", { type: "button", "data-testid": "import-merge-cancel", onclick: () => { merge.hidden = true; text.textContent = `${chosen.name}: not imported`; } }, "cancel"));
    merge.hidden = false;
  };
  const send = async (chosen, mergeMode = null) => {
    start.disabled = true;
    bar.hidden = false;
    bar.max = chosen.size || 1;
    bar.value = 0;
    try {
      const job = await whileWorking("upload", uploadImport(chosen, kind.value, (sent, total) => {
        bar.max = total || 1;
        bar.value = sent;
        text.textContent = `uploading ${chosen.name}: ${fmtBytes(sent)} of ${fmtBytes(total)}`;
      }, mergeMode));
      onQueued(job); // the Jobs panel shows it first: the words below point at it
      text.textContent = `${chosen.name} uploaded${mergeMode ? ` (merge: ${mergeMode.replace("-", " ")})` : ""}: import job #${job.id} queued (its progress and then what it gave: in the Jobs panel, ${jobsPlace(root)})`;
      whileWorking("job", followImport(job, chosen.name, text)); // the page's work until the import ends (busy.js)
    } catch (err) {
      text.textContent = "";
      if (err.status === 409 && err.body && err.body.current && err.body.current.merge_modes) offerMerge(chosen, err);
      else showError(`import of ${chosen.name}: ${err.message}`);
    } finally {
      start.disabled = false;
      bar.hidden = true;
    }
  };
  start.addEventListener("click", () => {
    const chosen = file.files && file.files[0];
    if (!chosen) {
      text.textContent = "choose a zip first";
      return;
    }
    merge.hidden = true;
    send(chosen);
  });
  root.replaceChildren(el("h2", { title: "An uploaded zip of a dataset, imported as a job (admins)" }, "Import"),
    kind, file, start, bar, text, merge);
  root.hidden = false;
}
