// The system page's review pass: the frozen list of the queue's systems, in the order the queue
// had when the pass began (every page), stored on the server per user (/api/passes) and named in the page's
// address (`?pass=ID`, kept across a reload). A decision goes to the next system of the pass that is still
// pending (its status read now, GET .../place), wrapping round to the pass's start; j / k step through the
// pass's order; a fix never reorders it. When nothing pending is left after the system, the page says so with the pass's counts
// (data-testid="pass-finished") and a way back to the queue.

import { ApiError, startPass, visitPass, passPlace, listPasses, getPass, batchPass } from "./api.js";
import { BATCH_PARAM, batchIdOf, showBatchEnd } from "./batch.js";
import { el } from "./format.js";
import { readState, apiFilters, DEFAULT_SORT } from "./queuestate.js";

export const PASS_PARAM = "pass";

/** The pass id of a query string, or null. */
export function passIdOf(search = location.search) {
  const id = Number(new URLSearchParams(search).get(PASS_PARAM));
  return Number.isInteger(id) && id > 0 ? id : null;
}

/** `search` with the pass id set (or removed when `id` is null). */
export function withPass(search, id) {
  const q = new URLSearchParams(search);
  if (id === null) q.delete(PASS_PARAM);
  else q.set(PASS_PARAM, String(id));
  const s = q.toString();
  return s ? `?${s}` : "";
}

/** The queue's filters of a query string as POST /api/passes takes them (empty ones left out) and its sort. */
function queueOf(search) {
  const { sort, ...filters } = apiFilters(readState(search));
  return { filter: Object.fromEntries(Object.entries(filters).filter(([, v]) => v !== "" && v !== undefined)), sort };
}

/** "7 accepted · 1 rejected · 1 needs fix · 0 skipped": the person's own decisions in this pass, then the systems sent
 * back as fixed and those decided by others (or before the pass) when there are any, then those still pending. */
export function describeCounts(c = {}) {
  const others = [
    c.sent_back ? `${c.sent_back} sent back as fixed (to decide again)` : null,
    c.by_others ? `${c.by_others} decided by others or before this pass` : null,
  ].filter(Boolean);
  return [`${c.accepted ?? 0} accepted`, `${c.rejected ?? 0} rejected`, `${c.needs_fix ?? 0} needs fix`, ...others,
    `${c.skipped ?? 0} skipped`].join(" · ");
}

/** Systems of the pass still to decide: pending, or sent back as fixed. */
export function toDecide(c = {}) {
  return (c.skipped ?? 0) + (c.sent_back ?? 0);
}

/** True when a query string asks for a new pass (`?pass=new`: begin one even if an open pass of the same queue
 * holds the system). */
export function wantsNewPass(search = location.search) {
  return new URLSearchParams(search).get(PASS_PARAM) === "new";
}

export class ReviewPass {
  id = passIdOf();
  batchId = batchIdOf(); // a pass over a batch's sample (batch.js): counted "sample 3 of 59", its end the batch's
  place = null; // the shown system's place in the pass (GET .../place), null until known
  systemId = null; // the system `place` is of

  /** `bar`: where the pass's progress is drawn (the top bar's navs); `go(id)`: open a system of the pass. */
  constructor(bar, go) {
    this.go = go;
    this.progress = el("span", { class: "pass-progress muted", "data-testid": "pass-progress" });
    bar?.prepend(this.progress);
    this.panel = el("section", { class: "pass-finished", "data-testid": "pass-finished", role: "status", hidden: true });
    document.querySelector("main")?.before(this.panel);
  }

  /** The system `sys` is shown (page address `search`): begin the pass when the address names none, then
   * record the visit (the pass resumes here) and learn its place. Answers the address with the pass id
   * (unchanged when it had one). A pass the server no longer knows (404) is begun again. */
  async visit(sys, search) {
    const begin = async () => {
      if (this.batchId !== null) { // the sample's pass: the server's list, never the queue's
        this.id = (await batchPass(this.batchId)).id;
        return;
      }
      const { filter, sort } = queueOf(search);
      this.id = (await startPass(filter, sort, sys.id, wantsNewPass(search))).id;
    };
    if (this.id === null) await begin();
    let place;
    try {
      place = await visitPass(this.id, sys.id);
    } catch (err) {
      if (!(err instanceof ApiError && (err.status === 404 || err.status === 403))) throw err;
      await begin(); // a pass the server no longer has, or another user's link
      place = await visitPass(this.id, sys.id);
    }
    this.note(sys.id, place);
    return withPass(search, this.id);
  }

  /** The page shows `systemId` before the server answers its visit: its place in the bar at once, from what the
   * last place said of its neighbours (the next pending one, next, previous), else no number at all rather than
   * the previous system's. */
  arrive(systemId) {
    if (this.id === null || systemId === this.systemId || !this.place) return;
    const p = this.place;
    let index = null;
    if (systemId === p.next_pending_id) index = p.next_pending_index ?? null;
    else if (p.index !== null && systemId === p.next_id) index = p.index + 1;
    else if (p.index !== null && systemId === p.prev_id) index = p.index - 1;
    const where = index === null ? `… of ${p.total}` : `${index + 1} of ${p.total}`;
    this.progress.textContent = `${this.word()} ${where} · ${toDecide(p.counts)} pending`;
  }

  note(systemId, place) {
    this.systemId = systemId;
    this.place = place;
    const where = place.index === null ? `outside the ${this.word()}` : `${place.index + 1} of ${place.total}`;
    this.progress.textContent = `${this.word()} ${where} · ${toDecide(place.counts)} pending`;
    this.progress.title = `review pass ${place.pass_id}: your decisions in it: ${describeCounts(place.counts)} (skipped: still pending)`;
    if (!place.finished || place.index === null) this.hideFinished();
  }

  /** What the bar calls the pass: "sample" over a batch's sample, else "pass". */
  word() {
    return this.batchId !== null ? "sample" : "pass";
  }

  /** The place of `systemId`, read now (a decision just made counts): null without a pass. */
  async fresh(systemId) {
    if (this.id === null) return null;
    const place = await passPlace(this.id, systemId);
    this.note(systemId, place);
    return place;
  }

  /** The neighbours of the shown system in the pass's order (undefined: no place known yet). */
  nextId() {
    return this.place ? this.place.next_id : undefined;
  }

  prevId() {
    return this.place ? this.place.prev_id : undefined;
  }

  /** Say that nothing pending is left after the shown system: the counts, back to the queue, and the
   * systems stepped over, if any. */
  showFinished(place, queueUrl) {
    if (this.batchId !== null) return showBatchEnd(this.panel, this.batchId, queueUrl); // accept the others, or not
    const skipped = place.first_pending_id;
    this.panel.replaceChildren(
      el("strong", {}, "Pass finished: "),
      el("span", {}, "no other system of this pass is left pending. "),
      el("span", { "data-testid": "pass-counts", title: "your own decisions in this pass, then the rest" }, describeCounts(place.counts)),
      el("span", { class: "actions" },
        el("a", { href: queueUrl, class: "button", "data-testid": "pass-queue-link" }, "back to the queue (u)"),
        skipped !== null && skipped !== undefined
          ? el("button", { type: "button", "data-testid": "pass-skipped", onclick: () => this.go(skipped) },
            place.counts.sent_back ? `review the ${toDecide(place.counts)} left` : `review the ${place.counts.skipped} skipped`)
          : null),
    );
    this.panel.hidden = false;
    this.panel.scrollIntoView({ block: "nearest" });
  }

  hideFinished() {
    this.panel.hidden = true;
  }
}

/** The queue page's "resume" link: the user's newest pass with a pending system, or nothing. */
export async function resumeLink(container) {
  if (!container) return;
  try {
    const mine = await listPasses({ limit: 5 });
    const open = mine.find((p) => toDecide(p.counts) > 0 && p.total > 0);
    if (!open) return;
    const { id, position } = open;
    const full = await getPass(id);
    const at = full.systems[Math.min(position, full.systems.length - 1)];
    const sample = open.filter.batch_id !== undefined; // a batch's sample (batch.js): no queue's filters nor sort
    const q = new URLSearchParams(sample ? [[BATCH_PARAM, String(open.filter.batch_id)]]
      : Object.entries(open.filter).map(([k, v]) => [k === "game_id" ? "game" : k, String(v)]));
    for (const k of ["jac_min", "jac_max"]) if (q.has(k)) q.set(k, String(Number(q.get(k)) * 100));
    if (!sample && open.sort !== DEFAULT_SORT) q.set("sort", open.sort);
    q.set(PASS_PARAM, String(id));
    container.replaceChildren(el("a", { href: `/systems/${at}?${q}`, "data-testid": "resume-pass",
      title: `resume your review pass of ${new Date(open.created_at).toLocaleString()} at ${position + 1} of ${open.total}: `
        + `${open.counts.skipped} pending; ${describeCounts(open.counts)}` },
    // short: the header stays one line with the user's name and Log out at 1366 px
    `resume ${sample ? "sample" : "pass"} ${position + 1}/${open.total}`));
    container.hidden = false;
  } catch {
    // only an offer: the queue works without it
  }
}
