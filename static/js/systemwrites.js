// The system page's writes to its views: each write to a view goes after the previous one to that
// view and sends If-Match with the newest ETag the page knows of it (answers may arrive out of order); its
// answer, the recomputed system, is drawn unless the reviewer moved on; a 412 (someone else changed the view)
// draws their state and the conflict notice (conflict.js) with a re-apply. The ball, field-line, mirror and
// exclusion edits are such writes, and so are the undo / redo writes of the page's undo stack (lineseditor.js
// EditHistory): a line edit's undo writes the lines back, any other's POSTs /api/audit/{id}/undo.

import { ApiError, listAudit, patchBall, mirrorFieldLines, postExclusion, putFieldLines, undoEntry } from "./api.js";
import { isNum, showError, clearError, toast } from "./format.js";
import { isMirrorFlagged } from "./viewfacts.js";
import { showConflict } from "./conflict.js";
import { whileWorking } from "./busy.js";
import { describeState } from "./history.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);

export class ViewWrites {
  #page;
  saves = new Set(); // writes on their way to the server
  etags = new Map(); // frame id -> the newest ETag the page knows of the view
  chains = new Map(); // frame id -> the last write to that view (the next one waits for it)

  /** `page`: the system page (its shown `system`, `params`, `undoStack`, `render(system)`, `reload()`,
   * `load(id, push)`). */
  constructor(page) {
    this.#page = page;
  }

  /** Remember `etag` for a view unless the page already knows a newer version (answers may arrive out
   * of order; the version is the ETag's last number). */
  noteEtag(frameId, etag) {
    if (!etag) return;
    const version = (tag) => Number(/-(\d+)"$/.exec(tag || "")?.[1] ?? -1);
    if (version(etag) >= version(this.etags.get(frameId))) this.etags.set(frameId, etag);
  }

  /** Draw a write's answer ({body: the recomputed system view, etag}) unless the reviewer moved on. */
  afterWrite(shown, frameId, answer) {
    clearError();
    if (frameId !== null) this.noteEtag(frameId, answer.etag);
    const sys = answer.body;
    if (this.#page.system.id === shown && sys && Array.isArray(sys.views)) {
      const start = performance.now();
      // the written view's frame stays where it was in the window (under the pointer that just released a drag)
      // when the redraw adds or removes something above it (a doubt's banner, a chip line)
      const frameTop = () => [...$("views").children].find((p) => p.view?.frame_id === frameId)
        ?.querySelector(".frame")?.getBoundingClientRect().top;
      const before = frameId !== null ? frameTop() : undefined;
      this.#page.render(sys);
      const after = before !== undefined ? frameTop() : undefined;
      if (after !== undefined && Math.abs(after - before) >= 1) window.scrollBy(0, after - before);
      // the redraw's time: the script, then up to the painted frame (read by benchmarks/line_edit.py)
      performance.measure("v3d:render", { start });
      requestAnimationFrame(() => setTimeout(() => performance.measure("v3d:redraw", { start }), 0));
    }
  }

  /** A write to one view (`send(ifMatch)` -> {body, etag, entry}), after the previous write to that view so it
   * sends the ETag that one answered. `mine` says the change in words for the conflict notice and the undo's
   * toast; `done(system)` runs after the answer is drawn; `undoable` false: the write is not pushed on the
   * page's undo stack (a line edit pushes its own item, an undo is not undone by Ctrl+Z). */
  frameWrite(panel, frameId, mine, send, done = null, undoable = true) {
    const shown = this.#page.system.id;
    const previous = this.chains.get(frameId) || Promise.resolve();
    const save = previous.then(async () => {
      try {
        const answer = await send(this.etags.get(frameId));
        if (undoable && answer.entry) this.#page.undoStack.push({ kind: "entry", systemId: shown, frameId, entry: answer.entry, what: mine });
        this.afterWrite(shown, frameId, answer);
        if (done && this.#page.system.id === shown) done(answer.body);
      } catch (err) {
        panel.revert();
        if (err instanceof ApiError && err.status === 412) await this.conflict(panel, frameId, mine, send, done, err, undoable);
        else showError(err.message);
      }
    });
    this.chains.set(frameId, save);
    this.saves.add(whileWorking("save", save)); // the page's work until its answer is drawn (busy.js)
    save.finally(() => {
      this.saves.delete(save);
      if (this.chains.get(frameId) === save) this.chains.delete(frameId);
    });
  }

  /** Someone changed the view first: draw their state, say who and what, offer to re-apply. */
  async conflict(panel, frameId, mine, send, done, err, undoable = true) {
    this.noteEtag(frameId, err.body?.etag);
    await this.#page.reload();
    const index = this.#page.system.views.findIndex((v) => v.frame_id === frameId);
    const viewName = index >= 0 ? `V${index + 1}` : null;
    const name = index >= 0 ? this.#page.system.views[index].name : `frame ${frameId}`;
    showConflict($("conflict"), { error: err, what: `${viewName || "the view"} (${name})`, mine, viewName,
      reapply: () => this.frameWrite(panel, frameId, mine, send, done, undoable) });
    $("conflict").scrollIntoView({ block: "center" }); // a key (an undo) may have sent it from far down the page
  }

  saveBall(panel, detail) {
    const change = "box" in detail ? { box: detail.box } : { point: detail.point };
    if (detail.provenance) change.provenance = detail.provenance; // a doubt's suggestion: not evidence until placed
    const name = `${viewLabel(this.#page.system, detail.frameId)} (${panel.view?.name || "view"})`;
    this.frameWrite(panel, detail.frameId, `${viewLabel(this.#page.system, detail.frameId)} ball: ${describeState({ ball: change })}`,
      (etag) => patchBall(detail.frameId, change, this.#page.params, etag),
      detail.said ? () => toast(`${name}: ${detail.said}`) : null); // a key's fix says what it did, as m and x do
  }

  /** Send a view's edited field lines (lineseditor.js "lines-change"), draw the recalibrated system and
   * say what the edit did to the view's JaC; the write joins the page's undo stack. */
  saveLines(panel, detail) {
    const systemId = this.#page.system.id;
    const before = this.#page.system.views.find((v) => v.frame_id === detail.frameId);
    this.frameWrite(panel, detail.frameId, detail.what,
      (etag) => putFieldLines(detail.frameId, detail.lines, this.#page.params, etag).then((answer) => {
        this.#page.undoStack.push({ kind: "lines", systemId, frameId: detail.frameId, before: detail.before, after: detail.lines,
          entry: answer.entry, what: detail.what });
        return answer;
      }),
      (sys) => toast(`${detail.what}: ${jacChange(before, sys.views.find((v) => v.frame_id === detail.frameId))}`), false);
  }

  /** An undo or redo of the line stack: the write of `lines` to the item's view naming `undoOf`, on its
   * system's page (loaded first when another is shown). Answers the new audit entry, null when it failed
   * (a 412 shows the conflict notice). */
  async undoLines(item, lines, undoOf, kind) {
    if (this.#page.system?.id !== item.systemId) await this.#page.load(item.systemId, true);
    const index = this.#page.system?.views.findIndex((v) => v.frame_id === item.frameId) ?? -1;
    const panel = $("views").children[index];
    if (!panel) return null;
    let entry = null;
    const before = this.#page.system.views[index];
    panel.saving = true;
    this.frameWrite(panel, item.frameId, `${kind} of “${item.what}”`,
      (etag) => putFieldLines(item.frameId, lines, this.#page.params, etag, undoOf).then((answer) => {
        entry = answer.entry;
        return answer;
      }),
      (sys) => toast(`${kind}: ${item.what} · ${jacChange(before, sys.views.find((v) => v.frame_id === item.frameId))}`), false);
    await this.chains.get(item.frameId);
    return entry;
  }

  /** An undo or redo of any other edit (ball, exclusion, mirror, decisions): POST /api/audit/{undoOf}/undo on
   * the item's system's page (loaded first when another is shown), after the writes on their way. Answers the
   * new audit entry, null when it was refused (the resource changed since: said in the error bar). */
  async undoWrite(item, undoOf, kind) {
    // an undo right after a decision acts on the system decided, which the page had left: it goes back there and
    // says so, so that the next key is known to act on that system
    const away = this.#page.system?.id !== item.systemId;
    if (away) await this.#page.load(item.systemId, true);
    if (this.#page.system?.id !== item.systemId) return null;
    const write = (async () => {
      try {
        const answer = await undoEntry(undoOf, this.#page.params);
        this.afterWrite(item.systemId, item.frameId, answer);
        if (item.frameId === null && answer.etag && this.#page.system.id === item.systemId) this.#page.system.etag = answer.etag;
        const words = await this.entryWords(kind === "undo" ? undoOf : answer.entry, item.what);
        const name = this.#page.system.name;
        toast(`${kind === "undo" ? "Undone" : "Redone"}: ${words} (${name})${away ? `; back on ${name}: the next key acts here` : ""}`);
        if (away && this.#page.system.id === item.systemId) this.#page.showUndoneHere(words);
        return answer.entry;
      } catch (err) {
        showError(`${kind} of “${item.what}” refused: ${err.message}`);
        return null;
      }
    })();
    if (item.frameId !== null) { // the view's next write waits for it and sends the ETag it answers
      this.chains.set(item.frameId, write);
      this.saves.add(whileWorking("save", write));
      write.finally(() => {
        this.saves.delete(write);
        if (this.chains.get(item.frameId) === write) this.chains.delete(item.frameId);
      });
    }
    return write;
  }

  /** The server's words for audit entry `id` ("ball of V2 moved 3.0 px", without an "undo of entry N: "),
   * `fallback` when they cannot be read. */
  async entryWords(id, fallback) {
    try {
      const page = await listAudit({ system_id: this.#page.system.id, limit: 30 });
      const entry = page.items.find((e) => e.id === id);
      return entry?.summary?.replace(/^(undo|redo) of entry \d+: /, "") || fallback;
    } catch {
      return fallback;
    }
  }

  /** Replace a flagged view's field lines by their mirrored labelling, then draw the recomputed system. */
  applyMirror(panel, detail) {
    const name = panel.view?.name || "view";
    this.frameWrite(panel, detail.frameId, `${viewLabel(this.#page.system, detail.frameId)} mirrored field lines`,
      (etag) => mirrorFieldLines(detail.frameId, this.#page.params, etag),
      (sys) => {
        const after = sys.views.find((v) => v.frame_id === detail.frameId);
        toast(`${name}: mirrored labels applied${after && isMirrorFlagged(after) ? " (still flagged)" : ""}`);
      });
  }

  /** Exclude a view from the triangulation or restore it, then draw the recomputed system. */
  setExclusion(panel, detail) {
    const name = panel.view?.name || "view";
    this.frameWrite(panel, detail.frameId, `${viewLabel(this.#page.system, detail.frameId)} ${describeState({ excluded: detail.excluded })}`,
      (etag) => postExclusion(detail.frameId, detail.excluded, this.#page.params, etag),
      () => toast(`${name}: ${detail.excluded ? "excluded from" : "restored to"} the 3D ball`));
  }
}

/** "V2": the view's name on the page (its place among the system's views). */
function viewLabel(sys, frameId) {
  const i = (sys?.views || []).findIndex((v) => v.frame_id === frameId);
  return i >= 0 ? `V${i + 1}` : "the view";
}

/** A view's JaC at the admission gamma before -> after an edit, in words. */
function jacChange(before, after) {
  const jac = (v) => {
    const values = Object.values((v?.calibration || {}).jac || {});
    return values.length && isNum(values[0]) ? values[0].toFixed(3) : "refused";
  };
  return `JaC ${jac(before)} → ${jac(after)}`;
}
