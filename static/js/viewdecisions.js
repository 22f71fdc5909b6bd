// Per-view decisions on the system page: under each view's header, its ball decision (accept /
// reject / needs fix: POST /api/frames/{id}/review) and beside it the decision on its calibration (its field
// lines and the camera fitted to them: POST /api/frames/{id}/calibration-review), with the reason when an
// edit of the view's field lines set the calibration decision back to pending. Both are writes to the view:
// they go through the page's writes.frameWrite (systemwrites.js: If-Match with the view's ETag, one after the other, a 412 drawn
// with the conflict notice). Keys (in the page's one key table): Shift+A / R / F the selected view's ball,
// Shift+G / B / N its calibration (good / bad / needs fix).

import { postViewReview, postCalibrationReview } from "./api.js";
import { el, STATUS_LABEL } from "./format.js";

/** What each part of a view's decision is called, its request, and its keys (accept, reject, needs fix). */
export const PARTS = {
  view: { label: "View", what: "the view's ball", send: postViewReview, keys: ["A", "R", "F"],
    current: (view) => view.review?.status || "pending",
    reason: () => null },
  calibration: { label: "Calibration", what: "the view's calibration", send: postCalibrationReview, keys: ["G", "B", "N"],
    current: (view) => view.review?.calibration?.status || "pending",
    reason: (view) => view.review?.calibration?.reset_reason || null },
};
const STATUSES = ["accepted", "rejected", "needs_fix"];
const MARK = { accepted: "✓", rejected: "✗", needs_fix: "!" };

/** The line under the system's decision: when it was decided, or why it is pending again. */
export function decisionNote(review) {
  const status = review?.status || "pending";
  if (status === "pending" && review?.reset_reason) return `Pending again: ${review.reset_reason}`;
  const when = review?.decided_at ? new Date(review.decided_at) : null;
  return when && !Number.isNaN(when.getTime())
    ? `Decided ${when.toLocaleString()}: ${STATUS_LABEL[status] || status}.`
    : "Not decided yet.";
}

export class ViewDecisions {
  /** `page`: the system page (its `system`, `writes.frameWrite(panel, frameId, mine, send, done)`, `history`,
   * `params`, `decorate(panel, view)`: what the page adds to a panel after it is rebuilt); `toast(message)`. */
  constructor(page, toast) {
    this.page = page;
    this.toast = toast;
  }

  /** Draw (again) the decision bar of the view `panel` shows (after every panel.update: it rebuilds). */
  attach(panel, view) {
    const article = panel.querySelector("article.view");
    if (!article) return;
    article.querySelector(".view-decisions")?.remove();
    // a part of the view with no decision of its own reads the system's decision, which covers it
    const system = this.page.system?.review?.status || "pending";
    const groups = Object.entries(PARTS).map(([part, p]) => {
      const current = p.current(view);
      const inherited = current === "pending" && system !== "pending";
      const badge = inherited
        ? el("span", { class: `badge ${system} inherited`, "data-testid": `${part}-decision-status`,
          title: `no decision on ${p.what} of its own: the system's (${STATUS_LABEL[system]}) covers it` },
        `${STATUS_LABEL[system]} with the system`)
        : el("span", { class: `badge ${current}`, "data-testid": `${part}-decision-status` }, STATUS_LABEL[current] || current);
      return el("span", { class: "decision-group", "data-part": part },
        el("span", { class: "muted" }, `${p.label} `),
        badge,
        ...STATUSES.map((status, i) => el("button", {
          type: "button", class: `${status}${current === status ? " current" : ""}`,
          "data-testid": "view-decision", "data-part": part, "data-status": status,
          title: `${STATUS_LABEL[status]}: ${p.what} (Shift+${p.keys[i]} on the selected view)`,
          onclick: () => this.decide(panel, part, status),
        }, MARK[status])));
    });
    const reason = PARTS.calibration.reason(view);
    const bar = el("div", { class: "view-decisions", "data-testid": "view-decisions", "data-frame-id": view.frame_id },
      ...groups,
      reason ? el("div", { class: "reason bad", "data-testid": "calibration-reset-reason" }, reason) : null);
    article.querySelector("header")?.after(bar);
  }

  /** Decide `part` ("view" or "calibration") of the view `panel` shows; false when it cannot now. */
  decide(panel, part, status) {
    const view = panel?.view;
    const p = PARTS[part];
    if (!view || !p || !STATUSES.includes(status) || !this.page.system) return false;
    const sys = this.page.system;
    const index = sys.views.findIndex((v) => v.frame_id === view.frame_id);
    const name = index >= 0 ? `V${index + 1}` : view.name;
    this.page.writes.frameWrite(panel, view.frame_id, `${name} ${p.label.toLowerCase()}: ${STATUS_LABEL[status]}`,
      (etag) => p.send(view.frame_id, status, "", etag),
      (review) => {
        const shown = this.page.system.views.find((v) => v.frame_id === view.frame_id);
        if (!shown || !review) return;
        shown.review = review;
        panel.update(shown, {});
        this.page.decorate(panel, shown); // this bar again, and the page's zoom
        this.page.history.load(this.page.system, this.page.params);
        this.toast(`${name} ${p.label.toLowerCase()}: ${STATUS_LABEL[status]}`);
      });
    return true;
  }

  /** The key-table entries (keys.js): Shift+A / R / F and Shift+G / B / N on `target()` (the selected view's
   * panel, or the only view's). */
  keyEntries(target) {
    return Object.entries(PARTS).map(([part, p]) => ({
      keys: p.keys,
      show: p.keys.map((k) => `⇧${k}`),
      does: `the selected view's ${part === "view" ? "ball" : "calibration"}: accept / reject / needs fix`,
      run: (e) => this.decide(target(), part, STATUSES[p.keys.indexOf(e.key)]),
    }));
  }
}
