// Field-line editing of one view: drag a point, add a point to a line (double-click on it),
// delete a point or a whole line, relabel a line (the class chosen from the pitch model's list, served by
// GET /api/pitch-model, with the projected model line of that class highlighted), draw a new line of a
// class. Every change is one "lines-change" event {frameId, lines (the view's complete new lines), what}
// that the page sends as PUT /api/frames/{id}/field-lines; the recomputed view comes back and is drawn.
// Without edit mode the lines are drawn as before; the classes the calibration fits worst are marked with
// their residual (px) in every mode.
//
// Contract of the browser tests: each annotated point of the main frame is an SVG circle with
// data-testid="line-point", data-frame-id, data-class (SoccerNet class), data-polyline, data-index.
//
// EditHistory is the page's one undo / redo stack of its own writes (field lines, ball, exclusion, mirror,
// decisions): an undo is a new write naming the entry it undoes (for field lines a write of the earlier lines
// with `undo_of`, for the others POST /api/audit/{id}/undo), so the server audits it as that edit's undo.

import { getPitchModel } from "./api.js";
import { whileWorking } from "./busy.js";
import { el, svg, isNum, pointerImagePx } from "./format.js";
import { DragPreview, previewText } from "./linepreview.js";

/** How many of the worst-fitting classes are marked. */
const WORST_SHOWN = 3;
/** Handle radius (screen px) of a point in edit mode, and of its hit area. */
const HANDLE_PX = 4;
const HIT_PX = 9;
/** Two presses closer in time (ms) are a double click. */
const DOUBLE_MS = 400;

/** The calibration's per-class residuals, largest first: [[class, px], ...] (at most `n`). */
export function worstClasses(view, n = WORST_SHOWN) {
  const residuals = (view.calibration || {}).residuals_px || {};
  return Object.entries(residuals).filter(([, px]) => isNum(px)).sort((a, b) => b[1] - a[1]).slice(0, n);
}

/** How bad a class's residual is for the view: "bad" beyond the first JaC threshold (the admission's:
 * its gamma times the image diagonal, the distance a point may lie off its class's projection and still
 * count), "warn" beyond half of it, else "fine". */
export function residualLevel(view, px) {
  const gammas = Object.keys((view.calibration || {}).jac || {}).map(Number).filter((g) => g > 0);
  const threshold = (gammas.length ? Math.min(...gammas) : 0.005) * Math.hypot(view.width, view.height);
  return px > threshold ? "bad" : px > threshold / 2 ? "warn" : "fine";
}

const copyLines = (lines) => structuredClone(lines || {});
const roundPx = (p) => [Math.round(p[0] * 10) / 10, Math.round(p[1] * 10) / 10];
const pointsAttr = (pts) => pts.map((p) => p.join(",")).join(" ");

/** Index of the segment of `pts` nearest to `p` (the point goes after its start). */
function nearestSegment(pts, p) {
  let best = 0;
  let bestD = Infinity;
  for (let i = 0; i + 1 < pts.length; i++) {
    const [a, b] = [pts[i], pts[i + 1]];
    const dx = b[0] - a[0], dy = b[1] - a[1];
    const t = Math.max(0, Math.min(1, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy || 1)));
    const d = Math.hypot(a[0] + t * dx - p[0], a[1] + t * dy - p[1]);
    if (d < bestD) [best, bestD] = [i, d];
  }
  return best;
}

export class LineEditor {
  editing = false;
  selected = null; // {cls, poly, index (null: the whole line)}
  chosen = null; // the class of the class list: a relabel's target, a new line's class
  #live = null; // lines being dragged (image px)
  #drag = null;
  #drawing = null; // points of a new line being drawn
  #bar = null;
  #lastPress = null; // {what, t, x, y} of the last press on a line or the drawing canvas

  /** `panel`: the <v3d-view> (its `view`, `redraw()`, `redrawSoon()`, `saving`). */
  constructor(panel) {
    this.panel = panel;
    this.preview = new DragPreview(() => this.panel.redrawSoon());
  }

  get view() {
    return this.panel.view;
  }

  /** The view was drawn again (the server's answer, or another view): forget what was being dragged; keep
   * the mode, and the selection when it still names a line. */
  update(frameChanged) {
    this.#live = null;
    this.#drag = null;
    this.preview.clear();
    if (frameChanged) {
      this.editing = false;
      this.selected = null;
      this.#drawing = null;
    }
    const polys = this.selected && (this.view.field_lines || {})[this.selected.cls];
    if (!polys || !polys[this.selected.poly]) this.selected = null;
    else if (this.selected.index !== null && this.selected.index >= polys[this.selected.poly].length) this.selected.index = null;
  }

  /** After a failed save: the lines as the server has them. */
  revert() {
    this.#live = null;
    this.#drag = null;
    this.preview.clear();
  }

  /** The view as drawn: during a drag, with the preview's calibration (JaC, residuals) in place of the stored one. */
  shownView() {
    const answer = this.preview.answer;
    return answer ? { ...this.view, calibration: answer } : this.view;
  }

  /** The projected pitch to draw: the drag preview's camera's, else the stored camera's. */
  pitchLines() {
    return this.preview.answer ? this.preview.answer.pitch_lines || [] : this.view.pitch_lines || [];
  }

  lines() {
    return this.#live || this.view.field_lines || {};
  }

  // ----- the view card's parts --------------------------------------------------------------
  /** The toggle button for the view's actions. */
  toggleButton() {
    return el("button", { type: "button", "data-testid": "edit-lines", class: this.editing ? "current" : "",
      title: "Edit the field lines: drag a point, double-click a line to add one, Del a point, Shift+Del a line (e)",
      onclick: () => this.toggle() }, this.editing ? "done editing lines" : "edit lines");
  }

  /** "Worst lines": the classes the calibration fits worst, with their residual (px). */
  facts() {
    const worst = worstClasses(this.view);
    if (!worst.length) return [];
    return [
      el("dt", { title: "The classes whose annotated points lie farthest from the calibrated camera's projection of the model (mean distance, px): the first lines to check" }, "Worst lines"),
      el("dd", { class: "mono", "data-testid": "worst-lines" },
        ...worst.flatMap(([cls, px], i) => [i ? " · " : null,
          el("span", { "data-testid": "worst-line", "data-class": cls, class: { bad: "bad", warn: "warn", fine: "muted" }[residualLevel(this.view, px)] },
            `${cls.trim()} ${px.toFixed(1)} px`)])),
    ];
  }

  /** The edit bar (shown in edit mode): class list, relabel, new line, delete. */
  bar() {
    const select = el("select", { "data-testid": "line-class", title: "The pitch model's classes: a relabel's target and a new line's class ([ / ] step, its projection highlighted)",
      onchange: (e) => { this.choose(e.currentTarget.value); e.currentTarget.blur(); } });
    const drawing = Boolean(this.#drawing);
    const sel = this.selected;
    this.#bar = el("div", { class: "lines-bar", "data-testid": "lines-bar", hidden: !this.editing },
      el("span", { class: "muted", "data-testid": "line-selection" },
        drawing ? `new ${this.chosen || "?"} line: click its points, Enter to finish, Esc to cancel`
          : sel ? `${sel.cls.trim()}${sel.index !== null ? ` · point ${sel.index + 1}` : " · whole line"}` : "click a point or a line"),
      select,
      el("button", { type: "button", "data-testid": "relabel-line", disabled: !sel || !this.chosen || drawing,
        title: "Give the selected line the chosen class (l)", onclick: () => this.relabel() }, "relabel"),
      drawing
        ? el("button", { type: "button", "data-testid": "finish-line", onclick: () => this.finishLine() }, "finish line")
        : el("button", { type: "button", "data-testid": "draw-line", disabled: !this.chosen,
          title: "Draw a new line of the chosen class: click its points (n)", onclick: () => this.startLine() }, "new line"),
      el("button", { type: "button", "data-testid": "delete-point", disabled: !sel || sel.index === null || drawing,
        title: "Delete the selected point (Del)", onclick: () => this.deletePoint() }, "delete point"),
      el("button", { type: "button", "data-testid": "delete-line", disabled: !sel || drawing,
        title: "Delete the selected line (Shift+Del)", onclick: () => this.deleteLine() }, "delete line"));
    getPitchModel().then((model) => {
      const current = this.chosen ?? sel?.cls ?? "";
      select.replaceChildren(el("option", { value: "" }, "class…"),
        ...model.classes.map((c) => el("option", { value: c.name, selected: c.name === current }, c.name.trim())));
    }).catch(() => select.replaceChildren(el("option", { value: "" }, "classes unavailable")));
    return this.#bar;
  }

  #refreshBar() {
    if (this.#bar?.isConnected) this.#bar.replaceWith(this.bar());
    this.panel.querySelector("[data-testid=edit-lines]")?.replaceWith(this.toggleButton());
  }

  // ----- drawing ----------------------------------------------------------------------------
  /** Draw the annotated lines into `g` (an SVG group in image px; `s` = one screen px in image px),
   * the chosen class's projected model line highlighted and the worst classes marked. */
  drawLines(g, s, isMain) {
    const v = this.shownView();
    const lines = this.lines();
    if (this.chosen && this.editing) {
      for (const line of this.pitchLines()) {
        if (line.class !== this.chosen || !line.points || line.points.length < 2) continue;
        g.append(svg("polyline", { class: "pitch-hl", points: pointsAttr(line.points),
          "data-testid": isMain ? "model-line-highlight" : null, "data-class": line.class },
        svg("title", { text: `projected model: ${line.class}` })));
      }
    }
    const worst = new Map(worstClasses(v));
    for (const [cls, polylines] of Object.entries(lines)) {
      const bad = worst.has(cls) && residualLevel(v, worst.get(cls)) !== "fine";
      polylines.forEach((pts, poly) => {
        const sel = this.selected && this.selected.cls === cls && this.selected.poly === poly;
        if (pts.length > 1) {
          g.append(svg("polyline", { class: `annot-line${bad ? " worst" : ""}${sel ? " selected" : ""}`, points: pointsAttr(pts) }));
        }
        if (worst.has(cls) && isMain && this.editing && pts.length) {
          const [x, y] = pts[Math.floor(pts.length / 2)];
          g.append(svg("text", { class: `worst-label ${residualLevel(v, worst.get(cls))}`, x: x + 6 * s, y: y - 6 * s, "font-size": 11 * s, "data-testid": "worst-line-label",
            "data-class": cls, text: `${cls.trim()} ${worst.get(cls).toFixed(1)} px` }));
        }
        if (!this.editing || !isMain || this.#drawing) { // else drawHandles draws them, grabbable
          pts.forEach((p, index) => g.append(this.#point(cls, poly, index, p, 2.2 * s, isMain, bad)));
        }
      });
    }
    const answer = this.preview.answer;
    if (answer && isMain) {
      g.append(svg("text", { class: `preview-badge${answer.admitted ? "" : " bad"}`, x: 8 * s, y: v.height - 10 * s,
        "font-size": 13 * s, "data-testid": "drag-preview", "data-drawn": this.preview.drawn,
        "data-jac": Object.values(answer.jac || {})[0] ?? "", text: previewText(answer) },
      svg("title", { text: answer.differs || "The calibration these lines would give the view, computed as the release computes it; nothing is stored until the release" })));
    }
  }

  /** In edit mode, the grabbable parts, drawn last (above the ball's box): each line's hit stroke
   * (click: select it, double-click: add a point there) and each point's handle (drag: move it). */
  drawHandles(g, root, s) {
    if (!this.editing) return;
    const lines = this.lines();
    if (this.#drawing) {
      const v = this.view;
      const canvas = svg("rect", { class: "line-canvas", x: 0, y: 0, width: v.width, height: v.height, "data-testid": "line-canvas" });
      canvas.addEventListener("pointerdown", (e) => {
        if (e.button !== 0) return;
        e.preventDefault();
        e.stopPropagation();
        if (this.#double(e, "draw")) {
          this.finishLine();
          return;
        }
        const p = pointerImagePx(root, e);
        if (p) this.#drawing.push(roundPx(p));
        this.panel.redraw();
      });
      g.append(canvas);
      if (this.#drawing.length) {
        g.append(svg("polyline", { class: "annot-line drawing", points: pointsAttr(this.#drawing) }));
        for (const p of this.#drawing) g.append(svg("circle", { class: "annot drawing", cx: p[0], cy: p[1], r: HANDLE_PX * s }));
      }
      return;
    }
    const shown = this.shownView();
    const worst = new Map(worstClasses(shown));
    for (const [cls, polylines] of Object.entries(lines)) { // every line's hit stroke first, below every point
      polylines.forEach((pts, poly) => {
        if (pts.length > 1) {
          const hit = svg("polyline", { class: "line-hit", points: pointsAttr(pts), "stroke-width": 2 * HIT_PX * s,
            "data-testid": "line-hit", "data-class": cls, "data-polyline": poly });
          hit.addEventListener("pointerdown", (e) => {
            if (e.button !== 0) return;
            e.preventDefault();
            e.stopPropagation();
            const p = pointerImagePx(root, e);
            if (this.#double(e, `${cls}/${poly}`) && p) this.insertPoint(cls, poly, p);
            else this.select({ cls, poly, index: null });
          });
          g.append(hit);
        }
      });
    }
    for (const [cls, polylines] of Object.entries(lines)) {
      polylines.forEach((pts, poly) => {
        pts.forEach((p, index) => {
          const dot = this.#point(cls, poly, index, p, HANDLE_PX * s, true, worst.has(cls) && residualLevel(shown, worst.get(cls)) !== "fine");
          dot.classList.add("handle-pt");
          dot.addEventListener("pointerdown", (e) => this.#startDrag(e, root, cls, poly, index));
          g.append(dot);
        });
      });
    }
  }

  /** True when `e` is the second press of a double click on `what` (the overlay is drawn again after
   * the first, so the browser's dblclick, which needs one element under both, never comes). */
  #double(e, what) {
    const last = this.#lastPress;
    this.#lastPress = { what, t: e.timeStamp, x: e.clientX, y: e.clientY };
    const again = last && last.what === what && e.timeStamp - last.t < DOUBLE_MS && Math.hypot(e.clientX - last.x, e.clientY - last.y) < 5;
    if (again) this.#lastPress = null;
    return Boolean(again);
  }

  #point(cls, poly, index, p, r, isMain, bad) {
    const sel = this.selected && this.selected.cls === cls && this.selected.poly === poly
      && (this.selected.index === null || this.selected.index === index);
    return svg("circle", { class: `annot${bad ? " worst" : ""}${sel ? " selected" : ""}`, cx: p[0], cy: p[1], r,
      ...(isMain ? { "data-testid": "line-point", "data-frame-id": this.view.frame_id, "data-class": cls, "data-polyline": poly, "data-index": index } : {}) },
    svg("title", { text: `annotated: ${cls.trim()} (line ${poly + 1}, point ${index + 1})` }));
  }

  #startDrag(event, root, cls, poly, index) {
    if (event.button !== 0 || this.#drag) return;
    event.preventDefault();
    event.stopPropagation();
    // the whole drag reads the pointer through the view's screen matrix at the press: the page may move under a
    // drag (a preview's badge, a toast, an image arriving), and the point follows the pointer's own motion, not the
    // page's; read anew per move, a half-pixel shift of the card put a horizontal drag 2 px off in y
    const inverse = root.getScreenCTM()?.inverse();
    const start = pointerImagePx(root, event, inverse);
    if (!start) return;
    this.#drag = { cls, poly, index, start, origin: this.lines()[cls][poly][index], moved: false };
    this.#live = copyLines(this.view.field_lines);
    this.preview.begin();
    const move = (e) => {
      const d = this.#drag;
      const p = d && pointerImagePx(root, e, inverse);
      if (!p) return;
      const v = this.view;
      const x = Math.min(v.width, Math.max(0, d.origin[0] + p[0] - d.start[0]));
      const y = Math.min(v.height, Math.max(0, d.origin[1] + p[1] - d.start[1]));
      d.moved = d.moved || Math.hypot(p[0] - d.start[0], p[1] - d.start[1]) > 0.3;
      this.#live[cls][poly][index] = [x, y];
      if (d.moved) this.preview.push(v.frame_id, this.#live);
      this.panel.redrawSoon(); // moves faster than the screen draws are drawn once a frame
    };
    const up = (e) => {
      root.removeEventListener("pointermove", move);
      root.removeEventListener("pointerup", up);
      root.removeEventListener("pointercancel", up);
      const d = this.#drag;
      const lines = this.#live;
      this.#drag = null;
      this.#live = null;
      if (!d || e.type === "pointercancel" || !d.moved) {
        this.preview.end(false);
        this.select({ cls, poly, index });
        return;
      }
      this.preview.end(true); // its last answer stays drawn until the release's own answer is
      lines[cls][poly][index] = roundPx(lines[cls][poly][index]);
      this.selected = { cls, poly, index };
      this.#live = lines; // shown until the answer is drawn
      this.#send(lines, `moved point ${index + 1} of ${cls.trim()}`);
    };
    root.setPointerCapture(event.pointerId);
    root.addEventListener("pointermove", move);
    root.addEventListener("pointerup", up);
    root.addEventListener("pointercancel", up);
  }

  // ----- actions (buttons and keys) ---------------------------------------------------------
  toggle(on = !this.editing) {
    this.editing = on;
    if (!on) {
      this.#drawing = null;
      this.selected = null;
    }
    this.#refreshBar();
    this.panel.redraw();
    return true;
  }

  select(selection) {
    this.selected = selection;
    if (selection && !this.#drawing) this.chosen = selection.cls;
    this.#refreshBar();
    this.panel.redraw();
  }

  /** Choose a class of the pitch model (a relabel's target, a new line's class): its projection shows. */
  choose(cls) {
    this.chosen = cls || null;
    this.#refreshBar();
    this.panel.redraw();
  }

  /** Step the chosen class through the pitch model's list. */
  async step(delta) {
    if (!this.editing) return false;
    const names = (await getPitchModel()).classes.map((c) => c.name);
    const i = names.indexOf(this.chosen);
    this.choose(names[(i + delta + names.length) % names.length]);
    return true;
  }

  #send(lines, what) {
    if (this.panel.saving) return false;
    this.panel.saving = true;
    this.panel.dispatchEvent(new CustomEvent("lines-change", {
      detail: { frameId: this.view.frame_id, lines, before: copyLines(this.view.field_lines), what }, bubbles: true }));
    return true;
  }

  insertPoint(cls, poly, p) {
    const lines = copyLines(this.view.field_lines);
    const pts = lines[cls][poly];
    const at = pts.length > 1 ? nearestSegment(pts, p) + 1 : pts.length;
    pts.splice(at, 0, roundPx(p));
    this.selected = { cls, poly, index: at };
    return this.#send(lines, `added a point to ${cls.trim()}`);
  }

  deletePoint() {
    const sel = this.selected;
    if (!this.editing || !sel || sel.index === null) return false;
    const lines = copyLines(this.view.field_lines);
    const pts = lines[sel.cls][sel.poly];
    pts.splice(sel.index, 1);
    if (!pts.length) this.#dropLine(lines, sel.cls, sel.poly);
    this.selected = pts.length ? { ...sel, index: null } : null;
    return this.#send(lines, `deleted point ${sel.index + 1} of ${sel.cls.trim()}`);
  }

  deleteLine() {
    const sel = this.selected;
    if (!this.editing || !sel) return false;
    const lines = copyLines(this.view.field_lines);
    this.#dropLine(lines, sel.cls, sel.poly);
    this.selected = null;
    return this.#send(lines, `deleted a ${sel.cls.trim()} line`);
  }

  #dropLine(lines, cls, poly) {
    lines[cls].splice(poly, 1);
    if (!lines[cls].length) delete lines[cls];
  }

  relabel(cls = this.chosen) {
    const sel = this.selected;
    if (!this.editing || !sel || !cls || cls === sel.cls) return false;
    const lines = copyLines(this.view.field_lines);
    const [pts] = lines[sel.cls].splice(sel.poly, 1);
    if (!lines[sel.cls].length) delete lines[sel.cls];
    (lines[cls] ||= []).push(pts);
    this.selected = { cls, poly: lines[cls].length - 1, index: null };
    return this.#send(lines, `relabelled a ${sel.cls.trim()} line as ${cls.trim()}`);
  }

  startLine() {
    if (!this.editing || !this.chosen || this.panel.saving) return false;
    this.#drawing = [];
    this.selected = null;
    this.#refreshBar();
    this.panel.redraw();
    return true;
  }

  finishLine() {
    const pts = this.#drawing;
    if (!pts) return false;
    this.#drawing = null;
    this.#refreshBar();
    if (pts.length < 2) {
      this.panel.redraw();
      return true;
    }
    const lines = copyLines(this.view.field_lines);
    (lines[this.chosen] ||= []).push(pts);
    this.selected = { cls: this.chosen, poly: lines[this.chosen].length - 1, index: null };
    return this.#send(lines, `drew a ${this.chosen.trim()} line`);
  }

  /** Esc: cancel the line being drawn, else drop the selection. */
  cancel() {
    if (this.#drawing) this.#drawing = null;
    else if (this.selected) this.selected = null;
    else return false;
    this.#refreshBar();
    this.panel.redraw();
    return true;
  }
}

/**
 * The page's undo / redo of its own field-line writes, while the page is open. An item is
 * {systemId, frameId, before, after, entry}: the lines before and after a write and its audit entry.
 * Undo writes `before` naming `entry` (undo_of); redo writes `after` naming the undo's entry.
 * `write(item, lines, undoOf)` -> Promise of the new audit entry id (null: the write failed, which
 * stops the stack: a 412 shows the conflict notice).
 */
export class EditHistory {
  done = [];
  undone = [];
  #turn = Promise.resolve(); // undos and redos run one after the other

  /** `write(item, state, undoOf, kind)`: the write of an undo or redo ("undo" / "redo"), answering its new
   * audit entry (null: failed, the stack is emptied); `settle()`: resolves when the page's writes on their way
   * are answered (so that the stack holds them); `onEmpty(kind)`: nothing to undo or redo; `older()`: when the
   * page has nothing of its own to undo (after a reload), the item of the user's last edit the server's history
   * holds, or null. */
  constructor(write, settle = async () => {}, onEmpty = () => {}, older = async () => null) {
    this.write = write;
    this.settle = settle;
    this.onEmpty = onEmpty;
    this.older = older;
  }

  push(item) {
    this.done.push(item);
    this.undone = [];
  }

  clear() {
    this.done = [];
    this.undone = [];
  }

  undo() {
    return this.#step(this.done, this.undone, "before", "undo");
  }

  redo() {
    return this.#step(this.undone, this.done, "after", "redo");
  }

  /** Take the newest item of `from`, write its `side` naming its entry, put it on `to` with the new entry. */
  #step(from, to, side, kind) {
    this.#turn = this.#turn.then(async () => {
      await this.settle();
      const item = from.pop() || (kind === "undo" ? await this.older() : null);
      if (!item) {
        this.onEmpty(kind);
        return false;
      }
      const entry = await this.write(item, item[side], item.entry, kind);
      if (entry === null) this.clear();
      else to.push({ ...item, entry });
      return true;
    });
    return whileWorking("undo", this.#turn); // the page's work until it is written and drawn (busy.js)
  }
}

/** The line editor's keys (in the page's one key table; `view()` is the selected view panel or null,
 * `history` the page's EditHistory). Entries return false when they do not apply, so that a key shared
 * with the ball (Delete) goes on to the ball's entry. */
export function lineKeys(view, history) {
  const editor = () => view()?.lines || null;
  return [
    { keys: ["e"], does: "edit the selected view's field lines, or stop", run: () => editor()?.toggle() ?? false },
    // while the view's lines are edited, Del never reaches the ball's entry (below in the table)
    { keys: ["Delete", "Backspace"], show: ["Del"], does: "delete the selected line point (when editing lines)",
      run: (e) => (editor()?.editing && !e.shiftKey ? (editor().deletePoint(), true) : false) },
    { keys: ["Delete", "Backspace"], show: ["Shift+Del"], does: "delete the selected line (when editing lines)",
      run: () => (editor()?.editing ? (editor().deleteLine(), true) : false) },
    { keys: ["[", "]"], does: "previous / next class of the pitch model (its projection highlighted)",
      run: (e) => editor()?.step(e.key === "]" ? 1 : -1) ?? false },
    { keys: ["l"], does: "relabel the selected line with the chosen class", run: () => editor()?.relabel() ?? false },
    { keys: ["n"], does: "draw a new line of the chosen class (click its points)", run: () => editor()?.startLine() ?? false },
    { keys: ["Enter"], does: "finish the line being drawn", run: () => editor()?.finishLine() ?? false },
    { keys: ["Escape"], show: ["Esc"], does: "cancel the line being drawn, or the line selection", run: () => editor()?.cancel() ?? false },
    { keys: ["z"], ctrl: true, show: ["Ctrl+Z"], does: "undo the page's last edit (ball, exclusion, mirror, lines, decision)",
      run: () => { history.undo(); } },
    { keys: ["Z", "y"], ctrl: true, show: ["Ctrl+Shift+Z", "Ctrl+Y"], does: "redo it", run: () => { history.redo(); } },
  ];
}
