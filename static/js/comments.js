// Comments pinned on a view, and the system's hand-off (needs fix returned to a person, sent back as fixed).
// GET /api/systems/{id}/comments lists them a page at a time (read here page after page, following next_offset: a
// system holds at most V3D_MAX_COMMENTS_PER_SYSTEM); each is drawn at its point on its view (viewdrawing.js reads
// pinsOf(frameId): numbered marks, grey once resolved) and listed with its thread in the Comments card
// (data-testid="review-comment"), where it is resolved or reopened. "Pin a comment" (reviewers, and the person the
// system is returned to) takes the next click on a view as the point; Shift+C jumps to the next unresolved
// comment. GET /api/systems/{id}/handoff says to whom the system is returned; the person it is returned to gets the
// "Send back as fixed" button (POST .../review {"status": "fixed"}). Text from the server is set as text only.

import { getMe, send } from "./api.js";
import { el, pointerImagePx, showError, toast } from "./format.js";
import { keepDraft } from "./drafts.js";
import { word } from "./words.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);

/** frame id -> its comments (the shown system's), as the views draw them. */
const PINS = new Map();

/** The comments pinned on view `frameId` of the shown system (with their number on the page). */
export function pinsOf(frameId) {
  return PINS.get(frameId) || [];
}

/** "12 Nov 17:03" in the reader's time. */
function when(iso) {
  const d = new Date(iso);
  return d.toLocaleString(undefined, { day: "numeric", month: "short", hour: "2-digit", minute: "2-digit" });
}

/** Most pages of comments read for one system (a system holds at most a few hundred: one or two pages). */
const MAX_PAGES = 50;

/** Every comment of system `id`, oldest first, page after page (each answer names its next_offset, null at the end). */
async function allComments(id) {
  const items = [];
  let offset = 0;
  for (let pages = 0; offset !== null && offset !== undefined && pages < MAX_PAGES; pages++) {
    const page = await send("GET", `/api/systems/${id}/comments?limit=500&offset=${offset}`);
    items.push(...page.items);
    offset = page.items.length ? page.next_offset : null;
  }
  return items;
}

export class CommentsCard {
  comments = [];
  handoff = null;
  me = null;
  pinning = false;
  draft = null;
  current = -1;

  /** @param page the system page (system.js): its views, its selection, its review */
  constructor(page) {
    this.page = page;
    $("comment-pin-start").addEventListener("click", () => this.startPin());
    $("comment-cancel").addEventListener("click", () => this.cancel());
    $("comment-save").addEventListener("click", () => this.save());
    $("comment-text").addEventListener("keydown", (e) => {
      if (e.key === "Escape") this.cancel();
      else if (e.key === "Enter" && !e.shiftKey) {
        e.preventDefault();
        this.save();
      }
    });
    // "fixed" carries no comment: the review box is the reviewer's (the note it answers is the hand-off's)
    $("send-fixed").addEventListener("click", () => this.page.review("fixed", ""));
    // the point of a new comment: the next press on a view while pinning (before the ball editor sees it)
    document.addEventListener("pointerdown", (e) => this.pickPoint(e), true);
    // a comment being written is a draft: kept when the session ends under it, warned of before the page is left
    keepDraft("pin", () => (this.draft && $("comment-text").value.trim() ? { ...this.draft, text: $("comment-text").value } : null),
      (kept) => this.reopen(kept));
  }

  /** Show the pin form at `draft`'s point ({frame_id, point}) of the shown system. */
  openForm(draft) {
    this.draft = draft;
    const index = this.viewIndex(draft.frame_id);
    $("comment-where").textContent = `on V${index + 1}, where you clicked`;
    $("comment-where").title = `V${index + 1} (${Math.round(draft.point[0])}, ${Math.round(draft.point[1])}): ${word("term", "pin").means}`;
    $("comment-form").hidden = false;
  }

  /** Open the pin form again with a comment kept while the person logged in again ({frame_id, point, text}). */
  reopen(kept) {
    if (this.viewIndex(kept.frame_id) < 0 || !Array.isArray(kept.point)) return;
    this.openForm({ frame_id: kept.frame_id, point: kept.point });
    $("comment-text").value = String(kept.text || "");
  }

  /** Read the comments and the hand-off of `sys` and draw them. */
  async load(sys) {
    const id = sys.id;
    try {
      const [me, list, handoff] = await Promise.all([
        getMe(), allComments(id), send("GET", `/api/systems/${id}/handoff`)]);
      if (this.page.system?.id !== id) return; // moved on meanwhile
      this.me = me;
      this.comments = list;
      this.handoff = handoff;
    } catch (err) {
      showError(`comments: ${err.message}`);
      return;
    }
    this.draw();
  }

  /** May the caller pin a comment (reviewers and admins, or the person the system is returned to)? */
  mayPin() {
    return Boolean(this.me && (this.me.role !== "annotator" || this.handoff?.may_send_fixed));
  }

  mayResolve(c) {
    return Boolean(this.me && (c.author === this.me.name || this.me.role !== "annotator" || this.handoff?.may_send_fixed));
  }

  viewIndex(frameId) {
    return (this.page.system?.views || []).findIndex((v) => v.frame_id === frameId);
  }

  draw() {
    PINS.clear();
    this.comments.forEach((c, i) => {
      c.number = i + 1;
      if (!PINS.has(c.frame_id)) PINS.set(c.frame_id, []);
      PINS.get(c.frame_id).push(c);
    });
    for (const panel of $("views").children) panel.redraw?.();
    const open = this.comments.filter((c) => !c.resolved).length;
    // "none" above a return note would say there is nothing to read where there is: the count is left out then
    $("comments-count").textContent = this.comments.length ? `${open} open of ${this.comments.length}`
      : this.handoff ? "" : "none";
    $("comments").replaceChildren(...this.comments.map((c, i) => this.item(c, i)));
    $("comment-pin-start").hidden = !this.mayPin();
    const h = this.handoff;
    $("handoff").textContent = h ? (h.open || h.fixed ? h.words : `${h.words} (closed: decided again)`) : "";
    $("handoff").hidden = !h;
    $("send-fixed").hidden = !h?.may_send_fixed;
    // an annotator decides nothing but "fixed" (the API answers 403): the reviewer's buttons are not offered
    for (const id of ["accept", "reject", "needs-fix", "review-card"]) $(id).hidden = this.me?.role === "annotator";
  }

  item(c, i) {
    const index = this.viewIndex(c.frame_id);
    // "on V2" for a person; the pixel (x from the frame's left, y from its top) on hover
    const where = `on V${index + 1}${c.point ? "" : ", the whole view"}`;
    const pixel = c.point ? `V${index + 1} (${Math.round(c.point[0])}, ${Math.round(c.point[1])}): ${word("term", "pin").means}` : null;
    const li = el("li", { class: `review-comment${c.resolved ? " resolved" : ""}${i === this.current ? " current" : ""}`,
      "data-testid": "review-comment", "data-id": String(c.id), "data-frame-id": String(c.frame_id), "data-resolved": String(c.resolved) },
    el("span", { class: "pin-no" }, String(c.number)),
    el("span", { class: "where", "data-testid": "review-comment-where", title: pixel }, where),
    el("span", { class: "text", "data-testid": "review-comment-text" }, c.text),
    el("span", { class: "muted by" }, `${c.author} · ${when(c.created_at)}${c.resolved ? ` · resolved by ${c.resolved_by}` : ""}`));
    if (this.mayResolve(c)) {
      const button = el("button", { type: "button", "data-testid": c.resolved ? "comment-reopen" : "comment-resolve" }, c.resolved ? "Reopen" : "Resolve");
      button.addEventListener("click", (e) => {
        e.stopPropagation();
        this.setResolved(c, !c.resolved);
      });
      li.append(button);
    }
    li.addEventListener("click", () => this.show(i));
    return li;
  }

  /** Select comment `i`'s view and bring it and the comment into sight. */
  show(i) {
    const c = this.comments[i];
    if (!c) return;
    this.current = i;
    const index = this.viewIndex(c.frame_id);
    if (index >= 0) {
      this.page.select(index);
      $("views").children[index]?.scrollIntoView({ block: "nearest" });
    }
    for (const li of $("comments").children) li.classList.toggle("current", li.dataset.id === String(c.id));
  }

  /** Shift+C: the next unresolved comment after the current one (wrapping around); a reason when there is none. */
  next() {
    const n = this.comments.length;
    for (let k = 1; k <= n; k++) {
      const i = (this.current + k + n) % n;
      if (!this.comments[i].resolved) {
        this.show(i);
        toast(`comment ${this.comments[i].number}: ${this.comments[i].text}`);
        return true;
      }
    }
    return n ? "every comment is resolved" : "no comment on this system";
  }

  async setResolved(c, resolved) {
    try {
      await send("POST", `/api/comments/${c.id}/${resolved ? "resolve" : "reopen"}`);
      await this.load(this.page.system);
    } catch (err) {
      showError(`comment ${c.number}: ${err.message}`);
    }
  }

  startPin() {
    if (!this.mayPin()) return;
    this.pinning = true;
    document.body.classList.add("pinning");
    toast("Click the point the comment is about on a view (Esc cancels)");
  }

  pickPoint(e) {
    if (!this.pinning) return;
    const frameSvg = e.target.closest?.("[data-testid=view-svg]");
    if (!frameSvg) return;
    const panel = frameSvg.closest("v3d-view");
    const p = pointerImagePx(frameSvg, e);
    if (!panel?.view || !p) return;
    e.preventDefault();
    e.stopPropagation();
    const v = panel.view;
    this.pinning = false;
    document.body.classList.remove("pinning");
    this.openForm({ frame_id: v.frame_id, point: [Math.min(Math.max(p[0], 0), v.width), Math.min(Math.max(p[1], 0), v.height)] });
    $("comment-text").focus();
  }

  cancel() {
    this.pinning = false;
    this.draft = null;
    document.body.classList.remove("pinning");
    $("comment-form").hidden = true;
    $("comment-text").value = "";
  }

  async save() {
    const text = $("comment-text").value.trim();
    if (!this.draft || !text || !this.page.system) return;
    try {
      await send("POST", `/api/systems/${this.page.system.id}/comments`, {
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ ...this.draft, text }),
      });
      this.cancel();
      await this.load(this.page.system);
      toast("comment pinned");
    } catch (err) {
      showError(`comment: ${err.message}`);
    }
  }

  /** The page's key table entries. */
  keyEntries() {
    return [
      { keys: ["C"], show: ["⇧C"], does: "next unresolved comment (its view selected)", run: () => this.next() },
      { keys: ["p"], does: "pin a comment: then click its point on a view",
        run: () => (this.mayPin() ? (this.startPin(), true)
          : !this.me ? "the page is still reading who you are: press p again in a moment"
            : "a comment is pinned by reviewers and admins, or by the person the system is returned to") },
      { keys: ["Escape"], show: ["Esc"], does: "cancel pinning a comment", run: () => (this.pinning ? (this.cancel(), true) : false) },
    ];
  }
}
