// The camera follows the drag. While a field-line point is dragged, the view's lines as the
// release would send them go to POST /api/frames/{id}/calibration-preview, which runs the edit's own calibration
// and stores nothing; its answer (camera, JaC, admission, per-class residuals, projected pitch) is drawn in place of
// the stored calibration until the release's own answer is drawn. At most one preview is in flight per view: the
// moves made meanwhile are coalesced into the next request (the newest lines only), and an answer that comes after
// its drag ended, or for an earlier drag, is dropped.

import { previewCalibration } from "./api.js";
import { fmtJac } from "./format.js";

export class DragPreview {
  /** The newest answer drawn for the current (or just released) drag, or null: draw the stored calibration. */
  answer = null;
  /** Answers drawn since the page opened (what the browser test's rate counts). */
  drawn = 0;
  #drag = 0; // the current drag's number
  #active = false;
  #inFlight = false;
  #next = null; // {drag, frameId, lines}: the newest lines moved while a preview was in flight

  /** `onAnswer()`: an answer is to be drawn (the view redraws its overlay). */
  constructor(onAnswer) {
    this.onAnswer = onAnswer;
  }

  /** A drag begins: the stored calibration is shown until its first answer. */
  begin() {
    this.#drag += 1;
    this.#active = true;
    this.#next = null;
    this.answer = null;
  }

  /** The dragged lines moved: preview them now, or as soon as the preview in flight is answered. */
  push(frameId, lines) {
    if (!this.#active) return;
    const job = { drag: this.#drag, frameId, lines: structuredClone(lines) };
    if (this.#inFlight) this.#next = job;
    else this.#send(job);
  }

  /** The drag ended: no more previews; the last answer stays drawn (`keep`, a release that commits) until
   * `clear()`, or goes at once. */
  end(keep) {
    this.#active = false;
    this.#next = null;
    if (!keep) this.answer = null;
  }

  /** The view was drawn from the server's answer (or the edit failed): the stored calibration is shown. */
  clear() {
    this.end(false);
  }

  #send(job) {
    this.#inFlight = true;
    previewCalibration(job.frameId, job.lines).then((answer) => {
      if (!this.#active || job.drag !== this.#drag) return; // released meanwhile, or another drag: stale
      this.answer = answer;
      this.drawn += 1;
      this.onAnswer();
    }, () => {}).finally(() => { // a refused preview (a 429, a point the edit would refuse) draws nothing
      this.#inFlight = false;
      const next = this.#next;
      this.#next = null;
      if (next && this.#active && next.drag === this.#drag) this.#send(next);
    });
  }
}

/** The preview's words, drawn on the dragged view: "preview · JaC 0.5% 91.2% · admitted", or the refusal. */
export function previewText(answer) {
  if (!answer) return "";
  if (answer.status !== "calibrated") return `preview · refused${answer.reason ? `: ${answer.reason}` : ""}`;
  const [gamma] = Object.keys(answer.jac || {});
  const pct = gamma ? String(Number((100 * Number(gamma)).toFixed(2))) : "";
  const retry = answer.retry ? ` · with the game's ${answer.retry}` : "";
  return `preview · JaC ${pct}% ${fmtJac(answer.jac?.[gamma])} · ${answer.admitted ? "admitted" : "not admitted"}${retry}`;
}
