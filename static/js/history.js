// The system page's history panel: the system's audit entries (its decisions and its views' edits),
// newest first, one line each (who, when, the change in words: the entry's summary; before -> after in its
// tooltip), with a one-click revert for
// reviewers. Also the one place that says an entry's change in words (the conflict notice uses it).

import { listAudit, revertEntry, getMe, ApiError } from "./api.js";
import { el, human } from "./format.js";

const ACTION_LABEL = {
  "ball.edit": "ball label",
  "field_lines.replace": "field lines",
  "field_lines.mirror": "mirrored lines",
  "view.exclusion": "exclusion",
  "view.review": "view review",
  "view.calibration_review": "calibration review",
  "system.review": "system review",
  "system.assign": "assignment",
  import: "import",
  recompute: "recompute",
  revert: "revert",
};
const HISTORY_LIMIT = 30;
const px = (values) => `[${values.map((v) => Math.round(v * 10) / 10).join(", ")}]`;

/** A recorded state ({ball}, {lines}, {excluded}, {review}, or an import's counts) in a few words. */
export function describeState(state) {
  if (!state || typeof state !== "object") return "—";
  if ("ball" in state) {
    const b = state.ball || {};
    if (Array.isArray(b.box)) return `box ${px(b.box)}`;
    if (Array.isArray(b.point)) return `point ${px(b.point)}`;
    return "no ball";
  }
  if ("lines" in state) {
    const lines = state.lines || {};
    const n = Object.values(lines).reduce((sum, polys) => sum + (Array.isArray(polys) ? polys.length : 0), 0);
    return `${n} line${n === 1 ? "" : "s"} (${Object.keys(lines).length} classes)`;
  }
  if ("excluded" in state) return state.excluded ? "excluded from the 3D ball" : "in the 3D ball";
  if ("assignee" in state) return state.assignee ? `assigned to ${state.assignee}` : "unassigned";
  if ("review" in state || "calibration_review" in state) {
    const r = state.review || state.calibration_review || {};
    return `${human(r.status || "pending")}${r.comment ? ` “${r.comment}”` : ""}`;
  }
  return Object.entries(state).filter(([, v]) => typeof v === "number").map(([k, v]) => `${v} ${human(k)}`).join(", ") || "—";
}

/** When, as a short local time (with the date when not today). */
export function when(iso) {
  const t = new Date(iso);
  if (Number.isNaN(t.getTime())) return "";
  return t.toDateString() === new Date().toDateString() ? t.toLocaleTimeString() : t.toLocaleString();
}

/** The entry's one line in words, as the server wrote it ("ball of V2 moved 12.3 px"; older entries get the
 * same words computed when read), after who and when: "ana, 12:03:04: ball of V2 moved 12.3 px". */
export function summaryLine(entry) {
  return `${entry.actor}, ${when(entry.at)}: ${entry.summary || ACTION_LABEL[entry.action] || entry.action}`;
}

/** "ana, 12:03:04: ball label of V2 box [..] -> box [..]". */
export function describeEntry(entry, viewName) {
  const what = ACTION_LABEL[entry.action] || entry.action;
  const where = viewName ? ` of ${viewName}` : "";
  const change = entry.before ? `${describeState(entry.before)} → ${describeState(entry.after)}` : describeState(entry.after);
  // an edit naming the entry it reverses without being a revert: a page's undo (or redo) of its own edit
  const undo = entry.reverts_id && entry.action !== "revert" ? ` (undo of entry ${entry.reverts_id})` : "";
  return `${entry.actor}, ${when(entry.at)}: ${what}${where}${undo}: ${change}`;
}

/** The question a revert refused as stale (409) asks, in the history's words: what the part is now, what the revert
 * would put back. */
export function revertQuestion(entry, viewName, current) {
  const what = `${ACTION_LABEL[entry.action] || entry.action}${viewName ? ` of ${viewName}` : ""}`;
  const now = current && typeof current === "object" ? ` It is now ${describeState(current)}.` : "";
  return `The ${what} changed after this entry (${summaryLine(entry)}).${now}\n\n`
    + `Revert anyway, overwriting the newer change? It becomes ${describeState(entry.before)}.`;
}

export class HistoryPanel {
  /** `root`: the panel's list element; `onReverted(answer)`: draw a revert's {body, etag}; `onError(msg)`. */
  constructor(root, { onReverted, onError }) {
    this.root = root;
    this.onReverted = onReverted;
    this.onError = onError;
    // reverts need the reviewer role; the server says which roles the user holds (its ranking, not a copy)
    this.mayRevert = getMe().then((me) => !me || (me.roles || []).includes("reviewer")).catch(() => true);
  }

  /** Read and draw the history of `system` (views named V1, V2, ... as on the page). */
  async load(system, params) {
    this.system = system;
    this.params = params;
    let page;
    try {
      page = await listAudit({ system_id: system.id, limit: HISTORY_LIMIT });
    } catch (err) {
      this.root.replaceChildren(el("li", { class: "muted" }, `history unavailable: ${err.message}`));
      return;
    }
    if (this.system !== system) return; // another system was drawn meanwhile
    const mayRevert = await this.mayRevert;
    const names = new Map(system.views.map((v, i) => [v.frame_id, `V${i + 1}`]));
    const rows = page.items.map((entry) => this.row(entry, names.get(entry.frame_id), mayRevert));
    if (!rows.length) rows.push(el("li", { class: "muted" }, "No change recorded yet."));
    if (page.total > page.items.length) rows.push(el("li", { class: "muted" }, `… ${page.total - page.items.length} older`));
    this.root.replaceChildren(...rows);
  }

  row(entry, viewName, mayRevert) {
    const text = summaryLine(entry);
    const button = entry.revertible && mayRevert
      ? el("button", { type: "button", class: "small", "data-testid": "history-revert", title: `Restore the state before entry ${entry.id}`,
        onclick: () => this.revert(entry, false, viewName) }, "revert")
      : null;
    return el("li", { "data-testid": "history-entry", "data-action": entry.action, "data-entry": entry.id,
      title: `entry ${entry.id}: ${describeEntry(entry, viewName)}` },
      el("span", { class: "history-text" }, text), button);
  }

  async revert(entry, force = false, viewName = null) {
    try {
      const answer = await revertEntry(entry.id, this.params, force);
      this.onReverted(answer);
    } catch (err) {
      if (err instanceof ApiError && err.status === 409 && !force) {
        // eslint-disable-next-line no-alert
        if (window.confirm(revertQuestion(entry, viewName, err.body?.current))) await this.revert(entry, true, viewName);
        return;
      }
      this.onError(err.message);
    }
  }
}
