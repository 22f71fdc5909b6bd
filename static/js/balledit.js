// Editing one view's ball label with the pointer and the keyboard: drag the box to move it, its corner to
// resize it (Shift keeps it square), draw a new box where the view has no label, drag a point; arrow keys and
// + / - move and grow it, saved after a pause. The label being edited is "live" (image pixels) until the
// edit ends; then the view dispatches "ball-change" {frameId, box} or {frameId, point} (rounded to 0.1 px),
// which the page saves. The view panel (overlay.js) owns one editor: `panel.ball`.

import { working } from "./busy.js";
import { pointerImagePx } from "./format.js";
import { boxCentre, clamp, validBox, validPoint } from "./viewfacts.js";

const MIN_BOX = 2; // smallest box side, image pixels

export class BallEditor {
  #panel;
  #live = null; // box or point being edited (image pixels)
  #drag = null;
  #nudgeTimer = null;
  #nudgeWork = null; // ends the page's work of a nudge waiting for its pause (busy.js)

  /** `panel`: the view panel (its `view`, `saving`, `redraw()`, `revert()`, `freezeZoom()`, and the events it
   * dispatches). */
  constructor(panel) {
    this.#panel = panel;
  }

  /** A drag is under way. */
  get dragging() {
    return Boolean(this.#drag);
  }

  /** The ball label shown: the live one while editing, else the view's valid box or point ({box} or {point},
   * image pixels); null when the view has none. */
  label() {
    const ball = this.#panel.view.ball || {};
    if (this.#live) return this.#live;
    if (ball.kind === "box" && validBox(ball.box)) return { box: ball.box };
    if (ball.kind === "point" && validPoint(ball.point)) return { point: ball.point };
    return null;
  }

  /** Drop the live label and the drag (a new view, or the saved label put back). */
  forget() {
    this.#live = null;
    this.#drag = null;
  }

  /** A pointer pressed on the label (`mode` "move", "resize" or "point") or on a view without one ("draw") in
   * the SVG `root` (the frame or the zoomed inset): follow it until it is released. */
  grab(event, root, mode) {
    if (event.button !== 0 || this.#panel.saving) return;
    event.preventDefault();
    event.stopPropagation();
    // the drag reads the pointer through the screen matrix at the press, as a line point's drag does (lineseditor.js):
    // the page moving under a drag does not move the label
    const inverse = root.getScreenCTM()?.inverse();
    const start = pointerImagePx(root, event, inverse);
    const label = mode === "draw" ? { box: [start[0], start[1], start[0], start[1]] } : this.label();
    if (!start || !label) return;
    this.#panel.freezeZoom(); // freeze the inset while dragging
    this.#drag = { mode, start, label: structuredClone(label), moved: false, root, pointerId: event.pointerId, inverse };
    const move = (e) => this.#onDrag(e);
    const up = (e) => {
      root.removeEventListener("pointermove", move);
      root.removeEventListener("pointerup", up);
      root.removeEventListener("pointercancel", up);
      this.#endDrag(e.type === "pointercancel");
    };
    root.setPointerCapture(event.pointerId);
    root.addEventListener("pointermove", move);
    root.addEventListener("pointerup", up);
    root.addEventListener("pointercancel", up);
  }

  #onDrag(event) {
    const d = this.#drag;
    if (!d) return;
    const p = pointerImagePx(d.root, event, d.inverse);
    if (!p) return;
    const v = this.#panel.view;
    let dx = p[0] - d.start[0], dy = p[1] - d.start[1];
    if (d.mode === "point") {
      const q = d.label.point;
      this.#live = { point: [clamp(q[0] + dx, 0, v.width), clamp(q[1] + dy, 0, v.height)] };
    } else if (d.mode === "draw") { // a new box where the view had no ball label
      const [sx, sy] = d.start;
      const x = clamp(p[0], 0, v.width), y = clamp(p[1], 0, v.height);
      this.#live = { box: [Math.min(sx, x), Math.min(sy, y), Math.max(sx, x, Math.min(sx, x) + MIN_BOX), Math.max(sy, y, Math.min(sy, y) + MIN_BOX)] };
    } else if (d.mode === "move") {
      const b = d.label.box;
      const [cx, cy] = boxCentre(b);
      dx = clamp(cx + dx, 0, v.width) - cx;
      dy = clamp(cy + dy, 0, v.height) - cy;
      this.#live = { box: [b[0] + dx, b[1] + dy, b[2] + dx, b[3] + dy] };
    } else {
      const b = d.label.box;
      let x2 = Math.max(b[0] + MIN_BOX, b[2] + dx);
      let y2 = Math.max(b[1] + MIN_BOX, b[3] + dy);
      if (event.shiftKey) { // keep the box square
        const side = Math.max(x2 - b[0], y2 - b[1]);
        x2 = b[0] + side;
        y2 = b[1] + side;
      }
      this.#live = { box: [b[0], b[1], x2, y2] };
    }
    d.moved = d.moved || Math.hypot(dx, dy) > 0.05;
    this.#panel.redraw();
  }

  #endDrag(cancelled) {
    const d = this.#drag;
    this.#drag = null;
    if (!d) return;
    if (cancelled || !d.moved || !this.#live) {
      this.#panel.revert();
      return;
    }
    this.#commit();
  }

  #commit() {
    const round = (x) => Math.round(x * 10) / 10;
    const detail = { frameId: this.#panel.view.frame_id };
    if (this.#live.box) detail.box = this.#live.box.map(round);
    else detail.point = this.#live.point.map(round);
    this.#panel.saving = true;
    this.#panel.dispatchEvent(new CustomEvent("ball-change", { detail, bubbles: true }));
  }

  /** Save now a keyboard edit still waiting for its pause (before a decision or moving on). */
  flush() {
    if (this.#nudgeTimer === null) return;
    clearTimeout(this.#nudgeTimer);
    this.#nudgeTimer = null;
    if (this.#live && !this.#panel.saving) this.#commit();
    this.#nudgeWork?.();
  }

  /** Keyboard editing: move by (dx, dy) and grow every side by `grow` image pixels; saved after a pause.
   * False when nothing moved (saving, dragging, no label, or a box that would fall under 2 px). */
  nudge(dx, dy, grow = 0) {
    if (this.#panel.saving || this.#drag) return false;
    const label = this.label();
    if (!label) return false;
    const v = this.#panel.view;
    if (label.box) {
      const b = label.box;
      if (b[2] - b[0] + 2 * grow < MIN_BOX || b[3] - b[1] + 2 * grow < MIN_BOX) return false;
      this.#live = { box: [b[0] + dx - grow, b[1] + dy - grow, b[2] + dx + grow, b[3] + dy + grow] };
    } else {
      this.#live = { point: [clamp(label.point[0] + dx, 0, v.width), clamp(label.point[1] + dy, 0, v.height)] };
    }
    this.#panel.freezeZoom();
    this.#panel.redraw();
    clearTimeout(this.#nudgeTimer);
    if (this.#nudgeTimer === null) this.#nudgeWork = working("nudge");
    this.#nudgeTimer = setTimeout(() => {
      this.#nudgeTimer = null;
      this.#commit(); // the save is the page's work from here (systemwrites.js)
      this.#nudgeWork();
    }, 450);
    return true;
  }
}
