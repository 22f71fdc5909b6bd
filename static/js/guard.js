// The accept guard: accepting a system with open label doubts first lists them in words
// (data-testid="accept-guard": each doubt's view, its name and the server's sentence), `Enter` accepts
// anyway, `Esc` cancels. A system of several views with no 3D ball is asked about the same way (one key press alone
// never accepts it: it would leave a release as a system without its 3D label). The server records the doubts an accept stood over in the decision's audit entry
// whether or not this dialog was shown (a script's accept too).

import { el, human, DOUBT_LABEL } from "./format.js";

/** The doubts of a system view that accuse a label (the ones an accept overrides). */
export function openLabelDoubts(sys) {
  return (sys?.doubts || []).filter((d) => d.accuses_label);
}

/** One doubt in words: "V2 (5_1.png) · ball off consensus: <the server's sentence>". */
export function doubtWords(sys, d) {
  const i = (sys.views || []).findIndex((v) => v.frame_id === d.frame_id);
  const where = i >= 0 ? `V${i + 1} (${sys.views[i].name})` : "the system";
  return `${where} · ${DOUBT_LABEL[d.kind] || human(d.kind)}: ${d.message}`;
}

/** Whether `sys` is a system of several views that has no 3D ball (a single view is reviewed for its calibration and
 * never has one). */
export function lacksBall(sys) {
  return (sys?.views || []).length > 1 && !sys.ball3d;
}

/** What the guard says of a system without a 3D ball. */
export const NO_BALL_WORDS = "It has no 3D ball: fewer than two of its views gave a ball that agrees, so a release "
  + "would hold it without its 3D label.";

export class AcceptGuard {
  #resolve = null;

  constructor() {
    this.list = el("ul", { "data-testid": "accept-guard-doubts" });
    this.confirmButton = el("button", { type: "button", class: "accept", "data-testid": "accept-guard-confirm",
      onclick: () => this.#close(true) }, "Accept anyway ", el("kbd", {}, "Enter"));
    this.cancelButton = el("button", { type: "button", "data-testid": "accept-guard-cancel",
      onclick: () => this.#close(false) }, "Cancel ", el("kbd", {}, "Esc"));
    this.title = el("h2", {}, "Accept over open doubts?");
    this.noBall = el("p", { class: "warn", "data-testid": "accept-guard-no-ball", hidden: true }, NO_BALL_WORDS);
    this.doubtsIntro = el("p", {}, "The geometry doubts these labels. Accepting keeps them as they are:");
    this.dialog = el("dialog", { class: "keys-help accept-guard", "data-testid": "accept-guard",
      "aria-label": "accept over open doubts" },
    this.title, this.noBall, this.doubtsIntro, this.list,
    el("div", { class: "guard-actions" }, this.confirmButton, this.cancelButton));
    this.dialog.addEventListener("keydown", (e) => {
      e.stopPropagation(); // the page's keys wait while the guard is open
      this.key(e);
    });
    this.dialog.addEventListener("cancel", (e) => {
      e.preventDefault();
      this.#close(false);
    });
    document.body.append(this.dialog);
  }

  get open() {
    return this.dialog.open;
  }

  /** A key while the guard is open (typed in it, or typed ahead and applied by the page's key queue): Enter accepts,
   * Esc cancels; true when it was one of them. */
  key(e) {
    if (e.key !== "Enter" && e.key !== "Escape") return false;
    e.preventDefault();
    this.#close(e.key === "Enter");
    return true;
  }

  /** Whether accepting `sys` asks the person first (open label doubts, or several views without a 3D ball). */
  asks(sys) {
    return openLabelDoubts(sys).length > 0 || lacksBall(sys);
  }

  /** Resolve true when `sys` may be accepted: at once without open label doubts, else when the person
   * confirms (Enter or the button); false when they cancel (Esc or the button). */
  ask(sys) {
    const doubts = openLabelDoubts(sys);
    const noBall = lacksBall(sys);
    if (!this.asks(sys)) return Promise.resolve(true);
    const over = doubts.length ? ` over ${doubts.length} open doubt${doubts.length === 1 ? "" : "s"}` : "";
    this.title.textContent = `Accept ${sys.name}${noBall ? " without a 3D ball" : ""}${over}?`;
    this.dialog.setAttribute("aria-label", noBall ? "accept without a 3D ball" : "accept over open doubts");
    this.noBall.hidden = !noBall;
    this.doubtsIntro.hidden = !doubts.length;
    this.list.replaceChildren(...doubts.map((d) => el("li", { "data-testid": "accept-guard-doubt", "data-kind": d.kind },
      doubtWords(sys, d))));
    this.dialog.showModal();
    this.confirmButton.focus();
    return new Promise((resolve) => {
      this.#resolve = resolve;
    });
  }

  #close(answer) {
    if (this.dialog.open) this.dialog.close();
    const resolve = this.#resolve;
    this.#resolve = null;
    resolve?.(answer);
  }
}
