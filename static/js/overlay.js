// <v3d-view>: one view of a multi-view system. The frame (or a blank canvas of the frame's size when the
// image is unavailable) with an SVG overlay in image pixels: projected pitch lines, annotated field-line
// points, the annotated ball box (red, draggable, resizable from its corner), the optimised box (blue) and
// the reprojected 3D ball (cross). A zoomed inset around the ball makes a 10-pixel box editable.
//
// The SVG viewBox is the image's pixel frame, so drawings and pointer positions map exactly at any display
// size (pointer positions go through getScreenCTM()). On release the element dispatches "ball-change"
// {frameId, box} or {frameId, point}; the page saves it and sets the recomputed view back.
// Its facts list and doubts bar are written by viewfacts.js.

import { el, svg, fmt, isNum, viewColour, STATUS_LABEL } from "./format.js";
import { LineEditor } from "./lineseditor.js";
import { getPitchLines } from "./api.js";
import {
  FIX_KEY, FIX_LABEL, boxCentre, clamp, isMirrorFlagged, notes, sameBox, validBox, validPoint, viewDoubtItems, viewFacts,
} from "./viewfacts.js";

const ZOOM_PX = 150; // displayed size of the zoom inset
const MIN_BOX = 2; // smallest box side, image pixels

export class ViewPanel extends HTMLElement {
  #view = null;
  #ctx = { index: 0, tau: null, rule: null, referenceWidth: null, viewCount: 0, doubts: [] };
  #imageState = "loading"; // loading | loaded | missing
  #imageUrl = null;
  #live = null; // box or point being dragged (image pixels)
  #drag = null;
  #redrawQueued = false; // a redrawSoon() waits for the next animation frame
  #zoomBox = null; // [x, y, size] of the inset, frozen while dragging
  #saving = false;
  #selected = false;
  #resizeObserver = null;
  #built = false;
  #nudgeTimer = null;
  lines = new LineEditor(this); // the field-line editor of this view (lineseditor.js)

  connectedCallback() {
    if (!this.#resizeObserver) {
      this.#resizeObserver = new ResizeObserver(() => this.#drawOverlays());
    }
    if (this.#built) this.#resizeObserver.observe(this.querySelector(".frame"));
  }

  disconnectedCallback() {
    this.#resizeObserver?.disconnect();
  }

  /** Set the view (system-view JSON) and its context {index, tau, rule, referenceWidth, viewCount, doubts}
   * (`doubts`: the system's doubts that name this view). */
  update(view, ctx) {
    const frameChanged = !this.#view || this.#view.frame_id !== view.frame_id;
    this.#view = view;
    this.#ctx = { ...this.#ctx, ...ctx };
    this.#live = null;
    this.#drag = null;
    this.#saving = false;
    this.#zoomBox = null;
    this.lines.update(frameChanged);
    if (frameChanged || view.image_url !== this.#imageUrl) this.#loadImage(view.image_url);
    this.#build();
    this.#loadPitchLines(view);
  }

  /** The view's projected pitch (`pitch_lines_url`, fetched once per camera) as `view.pitch_lines`, drawn when
   * it arrives; a view without a camera has none. */
  #loadPitchLines(view) {
    if (view.pitch_lines || !view.pitch_lines_url) {
      view.pitch_lines = view.pitch_lines || [];
      return;
    }
    getPitchLines(view.pitch_lines_url).then((lines) => {
      if (this.#view !== view) return; // a newer view came meanwhile: it fetches its own
      view.pitch_lines = lines;
      this.#drawOverlays();
    }, () => {}); // not drawn: the rest of the view stands without it
  }

  get view() {
    return this.#view;
  }

  get saving() {
    return this.#saving;
  }

  set saving(value) {
    this.#saving = value;
    const tag = this.querySelector("[data-testid=view-saving]");
    if (tag) tag.hidden = !value;
  }

  set selected(value) {
    this.#selected = value;
    this.querySelector(".view")?.classList.toggle("selected", value);
  }

  /** Draw the overlay again at the frame SVG's current viewBox (after a zoom or pan, or a change of the line
   * editor's live state). */
  redraw() {
    this.#redrawQueued = false;
    this.#drawOverlays();
  }

  /** Draw the overlay again at the next animation frame: the changes made meanwhile (a drag's pointer moves, a drag
   * preview's answer) are drawn once, so that a pointer sending moves faster than the screen is drawn never queues
   * redraws behind it. */
  redrawSoon() {
    if (this.#redrawQueued) return;
    this.#redrawQueued = true;
    requestAnimationFrame(() => {
      if (this.#redrawQueued) this.redraw();
    });
  }

  /** Put back the last saved label (after a failed save). */
  revert() {
    this.#live = null;
    this.#drag = null;
    this.lines.revert();
    this.saving = false;
    this.#drawOverlays();
  }

  #loadImage(url) {
    this.#imageUrl = url;
    if (!url) {
      this.#imageState = "missing";
      return;
    }
    this.#imageState = "loading";
    const probe = new Image();
    probe.onload = () => this.#imageSettled(url, "loaded");
    probe.onerror = () => this.#imageSettled(url, "missing");
    probe.src = url;
  }

  /** The frame's image arrived (or 404'd): redraw the backgrounds only, so a drag in progress goes on. */
  #imageSettled(url, state) {
    if (this.#imageUrl !== url) return;
    this.#imageState = state;
    const article = this.querySelector(".view");
    if (article) article.dataset.image = state;
    this.#drawOverlays();
  }

  // ----- DOM ------------------------------------------------------------------------------------
  #build() {
    const v = this.#view;
    const { index } = this.#ctx;
    const label = `V${index + 1}`;
    const ball = v.ball || {};
    const multiView = this.#ctx.viewCount !== 1;
    const viewDoubts = this.#ctx.doubts || [];
    const labelDoubts = viewDoubts.filter((d) => d.accuses_label);
    const doubtful = [...labelDoubts.map((d) => d.message), ...notes(v, multiView)];
    const excluded = Boolean(v.review?.excluded);

    const frameSvg = svg("svg", {
      viewBox: `0 0 ${v.width} ${v.height}`,
      preserveAspectRatio: "xMidYMid meet",
      "data-testid": "view-svg",
      "aria-label": `${label} ${v.name} with overlay`,
    });
    const zoomSvg = svg("svg", { "data-testid": "view-zoom", "aria-label": `${label} ball close-up` });
    if (!ball.kind) {
      // no ball label: drawing a box on the frame adds one
      frameSvg.classList.add("draw");
      frameSvg.addEventListener("pointerdown", (e) => {
        if ((!this.#currentLabel() || this.#drag) && !this.lines.editing) this.#startDrag(e, frameSvg, "draw");
      });
    }

    const doubtItems = viewDoubtItems(v, viewDoubts, excluded, this);
    const review = v.review && v.review.status && v.review.status !== "pending"
      ? el("span", { class: `badge ${v.review.status}` }, STATUS_LABEL[v.review.status] || v.review.status)
      : null;

    const article = el(
      "article",
      {
        class: `view${doubtful.length ? " doubtful" : ""}${excluded ? " excluded" : ""}${this.#selected ? " selected" : ""}`,
        "data-testid": "view",
        "data-frame-id": v.frame_id,
        "data-view-name": v.name,
        "data-image": this.#imageState,
        "data-doubtful": doubtful.length ? "true" : "false",
      },
      el(
        "header",
        {},
        el("span", { class: "tag", style: `background:${viewColour(index)}` }, label),
        el("span", { class: "name", title: v.name }, v.name),
        el("span", { class: "role" }, v.role || ""),
        ball.edited ? el("span", { class: "chip info", "data-testid": "view-edited" }, "box edited") : null,
        excluded ? el("span", { class: "chip bad", "data-testid": "view-excluded", title: "excluded from the triangulation by a reviewer (x to restore)" }, "excluded") : null,
        review,
        el("span", { class: "size" }, `${v.width}×${v.height}`),
      ),
      // the view's doubts and their fixes right under its header, above the frame: on screen without scrolling
      doubtItems.length ? el("div", { class: `view-doubts-bar${labelDoubts.length ? " bad" : ""}`, "data-testid": "view-doubts" }, doubtItems) : null,
      el(
        "div",
        { class: "frame" },
        frameSvg,
        el("span", { class: "saving", "data-testid": "view-saving", hidden: !this.#saving }, "saving…"),
      ),
      this.lines.bar(),
      el(
        "div",
        { class: "below" },
        el("div", { class: "zoom" }, zoomSvg, el("span", { class: "label", "data-testid": "zoom-label" }, "")),
        viewFacts(v, this.#ctx, this),
      ),
    );
    this.replaceChildren(article);
    // doubtful views first on the page (CSS order; their V numbers and keys stay): label doubts, then notes
    this.dataset.doubt = labelDoubts.length || (ball.kind && ball.provenance) ? "label" : doubtful.length ? "note" : "none";
    this.#built = true;
    this.#resizeObserver?.disconnect();
    if (this.isConnected) this.#resizeObserver?.observe(article.querySelector(".frame"));
    this.#drawOverlays();
  }

  // ----- overlay ------------------------------------------------------------------------------
  #currentLabel() {
    const ball = this.#view.ball || {};
    if (this.#live) return this.#live;
    if (ball.kind === "box" && validBox(ball.box)) return { box: ball.box };
    if (ball.kind === "point" && validPoint(ball.point)) return { point: ball.point };
    return null;
  }

  #zoomWindow() {
    if (this.#zoomBox) return this.#zoomBox;
    const v = this.#view;
    const ball = v.ball || {};
    let centre = null;
    let size = 0;
    if (ball.kind === "box" && validBox(ball.box)) {
      centre = boxCentre(ball.box);
      size = Math.max(ball.box[2] - ball.box[0], ball.box[3] - ball.box[1]);
    } else if (ball.kind === "point" && validPoint(ball.point)) centre = ball.point;
    else if (validPoint(v.reprojected_ball)) centre = v.reprojected_ball;
    if (v.optimised_box && validBox(v.optimised_box.box)) {
      size = Math.max(size, v.optimised_box.box[2] - v.optimised_box.box[0]);
      centre = centre || boxCentre(v.optimised_box.box);
    }
    if (!centre) return null;
    const side = Math.min(Math.max(6 * size, 72), Math.min(v.width, v.height));
    this.#zoomBox = [centre[0] - side / 2, centre[1] - side / 2, side];
    return this.#zoomBox;
  }

  #drawOverlays() {
    if (!this.#built || !this.#view) return;
    const v = this.#view;
    const frameSvg = this.querySelector("[data-testid=view-svg]");
    const zoomSvg = this.querySelector("[data-testid=view-zoom]");
    const width = frameSvg.getBoundingClientRect().width || 560;
    // the viewBox is the window shown (the whole frame, or a zoom: zoom.js): marks keep their screen size
    this.#drawInto(frameSvg, width / (frameSvg.viewBox.baseVal?.width || v.width), true);
    const zw = this.#zoomWindow();
    const zoomLabel = this.querySelector("[data-testid=zoom-label]");
    if (zw) {
      zoomSvg.setAttribute("viewBox", `${zw[0]} ${zw[1]} ${zw[2]} ${zw[2]}`);
      this.#drawInto(zoomSvg, ZOOM_PX / zw[2], false);
      zoomLabel.textContent = `ball ×${(ZOOM_PX / zw[2] / (width / v.width)).toFixed(1)}`;
    } else {
      zoomSvg.setAttribute("viewBox", `0 0 ${v.width} ${v.height}`);
      zoomSvg.replaceChildren(svg("text", { x: v.width / 2, y: v.height / 2, "text-anchor": "middle", class: "nodata",
        "font-size": v.width / 14, text: "no ball" }));
      zoomLabel.textContent = "";
    }
  }

  /** Draw the frame and overlay into `root`; `scale` = screen pixels per image pixel. */
  #drawInto(root, scale, isMain) {
    const v = this.#view;
    const s = 1 / scale; // one screen pixel, in image pixels
    const nodes = [];
    if (this.#imageState === "loaded") {
      nodes.push(svg("image", { href: v.image_url, x: 0, y: 0, width: v.width, height: v.height, preserveAspectRatio: "none" }));
    } else {
      nodes.push(svg("rect", { x: 0, y: 0, width: v.width, height: v.height, fill: "#101317" }));
      if (isMain) {
        nodes.push(svg("text", {
          x: 8 * s, y: 18 * s, class: "nodata", "font-size": 11 * s,
          text: this.#imageState === "loading" ? "loading image…" : `no image: blank ${v.width}×${v.height} canvas`,
        }));
      }
    }
    const g = svg("g", { "data-testid": isMain ? "overlay" : "zoom-overlay" });
    for (const line of this.lines.pitchLines()) { // a drag's preview camera while a line point moves
      if (!line.points || line.points.length < 2) continue;
      g.append(svg("polyline", { class: "pitch", points: line.points.map((p) => p.join(",")).join(" ") },
        svg("title", { text: `projected: ${line.class}` })));
    }
    this.lines.drawLines(g, s, isMain);
    const ball = v.ball || {};
    if (ball.edited && validBox(ball.original_box) && !(ball.kind === "box" && sameBox(ball.original_box, ball.box))) {
      g.append(this.#rect(ball.original_box, "box-prev", "imported box (before edits)"));
    }
    const opt = v.optimised_box;
    if (opt && validBox(opt.box)) {
      g.append(this.#rect(opt.box, "halo"));
      g.append(this.#rect(opt.box, "box-opt", `optimised box, d = ${fmt(opt.d_px, 1)} px`, "box-opt"));
    }
    if (validBox(v.precise_box)) { // the paper's Fig. 4: the reference Table 1 scores the boxes against
      g.append(this.#rect(v.precise_box, "box-precise", "precise box (Table 1 reference)", isMain ? "precise-box" : null));
    }
    for (const d of this.#ctx.doubts || []) {
      const epi = (d.evidence || {}).epipolar_px;
      if (Array.isArray(epi) && epi.length > 1 && epi.every(validPoint)) {
        g.append(svg("polyline", { class: "epipolar", points: epi.map((p) => p.join(",")).join(" "), "data-testid": isMain ? "epipolar" : null },
          svg("title", { text: "epipolar segment: where the other view's ray to its ball crosses this image" })));
      }
      const sb = d.suggestion && d.suggestion.box;
      if (validBox(sb)) {
        const sigma = d.suggestion.box_sigma_px;
        if (isNum(sigma) && sigma > 0) { // its uncertainty: a circle of 2 sigma around its centre
          const [cx, cy] = boxCentre(sb);
          g.append(svg("circle", { class: "sugg-sigma", cx, cy, r: Math.max(2 * sigma, 1.5 * s) },
            svg("title", { text: `where the ball may be (2 σ = ${(2 * sigma).toFixed(1)} px)` })));
        }
        g.append(this.#rect(sb, "box-sugg", `suggested box (${FIX_KEY.snap_box} snaps the ball label to it)`, isMain ? "suggested-box" : null));
      }
    }
    const label = this.#currentLabel();
    if (label && label.box) {
      const b = label.box;
      g.append(this.#rect(b, "halo"));
      g.append(this.#rect(b, "box-orig", "annotated ball box (drag to move, corner to resize)", "box-orig"));
      // hit area at least 18 screen pixels wide, so a 3-pixel box can be grabbed
      const [cx, cy] = boxCentre(b);
      const hw = Math.max((b[2] - b[0]) / 2, 9 * s), hh = Math.max((b[3] - b[1]) / 2, 9 * s);
      const hit = svg("rect", { class: "hit", x: cx - hw, y: cy - hh, width: 2 * hw, height: 2 * hh, "data-testid": isMain ? "ball-hit" : "zoom-ball-hit" });
      hit.addEventListener("pointerdown", (e) => this.#startDrag(e, root, "move"));
      g.append(hit);
      const hs = 8 * s;
      const handle = svg("rect", { class: "handle", x: b[2] - hs / 2 + (isMain ? hw - (b[2] - b[0]) / 2 : 0), y: b[3] - hs / 2 + (isMain ? hh - (b[3] - b[1]) / 2 : 0),
        width: hs, height: hs, "data-testid": isMain ? "ball-handle" : "zoom-ball-handle" });
      handle.addEventListener("pointerdown", (e) => this.#startDrag(e, root, "resize"));
      g.append(handle);
    } else if (label && label.point) {
      const p = label.point;
      const dot = svg("circle", { class: "point-orig", cx: p[0], cy: p[1], r: 4 * s, "data-testid": isMain ? "ball-point" : "zoom-ball-point" },
        svg("title", { text: "annotated ball point (drag to move)" }));
      dot.style.cursor = "move";
      dot.addEventListener("pointerdown", (e) => this.#startDrag(e, root, "point"));
      g.append(dot);
    }
    if (validPoint(v.reprojected_ball)) {
      const [x, y] = v.reprojected_ball;
      const c = label ? (label.box ? boxCentre(label.box) : label.point) : null;
      if (c) { // the error vector, from the label's centre to the reprojection (clipped at the frame's edge)
        g.append(svg("line", { class: "err-vec", x1: c[0], y1: c[1], x2: x, y2: y }));
      }
      // a cross with an open centre, so that the ball under it stays visible
      const a = 8 * s, gap = 3 * s;
      const d = [[-1, -1], [1, 1], [-1, 1], [1, -1]].map(([sx, sy]) => `M${x + sx * gap} ${y + sy * gap} L${x + sx * a} ${y + sy * a}`).join(" ");
      g.append(svg("path", { class: "halo", d }));
      g.append(svg("path", { class: "reproj", d, "data-testid": isMain ? "reprojected-ball" : null },
        svg("title", { text: `3D ball reprojected: (${x.toFixed(1)}, ${y.toFixed(1)})` })));
    }
    if (isMain) this.lines.drawHandles(g, root, s); // above the ball's box, in edit mode
    nodes.push(g);
    root.replaceChildren(...nodes);
  }

  #rect(b, cls, title, testid) {
    const r = svg("rect", { class: cls, x: b[0], y: b[1], width: b[2] - b[0], height: b[3] - b[1], "data-testid": testid });
    if (title) r.append(svg("title", { text: title }));
    return r;
  }

  // ----- editing ------------------------------------------------------------------------------
  #toImage(root, event) {
    const m = root.getScreenCTM();
    if (!m) return null;
    const p = new DOMPoint(event.clientX, event.clientY).matrixTransform(m.inverse());
    return [p.x, p.y];
  }

  #startDrag(event, root, mode) {
    if (event.button !== 0 || this.#saving) return;
    event.preventDefault();
    event.stopPropagation();
    const start = this.#toImage(root, event);
    const label = mode === "draw" ? { box: [start[0], start[1], start[0], start[1]] } : this.#currentLabel();
    if (!start || !label) return;
    this.#zoomWindow(); // freeze the inset while dragging
    this.#drag = { mode, start, label: structuredClone(label), moved: false, root, pointerId: event.pointerId };
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
    const p = this.#toImage(d.root, event);
    if (!p) return;
    const v = this.#view;
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
    this.#drawOverlays();
  }

  #endDrag(cancelled) {
    const d = this.#drag;
    this.#drag = null;
    if (!d) return;
    if (cancelled || !d.moved || !this.#live) {
      this.revert();
      return;
    }
    this.#commit();
  }

  #commit() {
    const round = (x) => Math.round(x * 10) / 10;
    const detail = { frameId: this.#view.frame_id };
    if (this.#live.box) detail.box = this.#live.box.map(round);
    else detail.point = this.#live.point.map(round);
    this.saving = true;
    this.dispatchEvent(new CustomEvent("ball-change", { detail, bubbles: true }));
  }

  /** Remove the ball label (the ball is not visible in this view). */
  removeLabel() {
    if (this.#saving || this.#drag || !(this.#view.ball || {}).kind) return false;
    this.saving = true;
    this.dispatchEvent(new CustomEvent("ball-change", { detail: { frameId: this.#view.frame_id, box: null }, bubbles: true }));
    return true;
  }

  /** Ask the page to replace this view's field lines by their mirrored labelling (flagged views only). */
  requestMirror() {
    if (this.#saving || this.#drag || !isMirrorFlagged(this.#view)) return false;
    this.saving = true;
    this.dispatchEvent(new CustomEvent("mirror-request", { detail: { frameId: this.#view.frame_id }, bubbles: true }));
    return true;
  }

  /** The first doubt of this view whose fix can be applied (a label-accusing one first). */
  fixableDoubt(action = null) {
    const ds = (this.#ctx.doubts || []).filter((d) => d.suggestion && FIX_LABEL[d.suggestion.action]
      && (!action || d.suggestion.action === action));
    return ds.find((d) => d.accuses_label) || ds[0] || null;
  }

  /** Apply a doubt's fix: snap the ball label to the suggested box, exclude the view, or mirror its labels. */
  applyFix(doubt) {
    if (this.#saving || this.#drag || !doubt || !doubt.suggestion) return false;
    const action = doubt.suggestion.action;
    if (action === "mirror_labels") return this.requestMirror();
    if (action === "exclude_view") return this.toggleExclusion(true);
    if (action === "snap_box" && validBox(doubt.suggestion.box)) {
      const round = (x) => Math.round(x * 10) / 10;
      this.saving = true;
      const provenance = ((doubt.suggestion.request || {}).body || {}).provenance; // the label keeps where it came from
      this.dispatchEvent(new CustomEvent("ball-change", { detail: { frameId: this.#view.frame_id, box: doubt.suggestion.box.map(round), provenance }, bubbles: true }));
      return true;
    }
    if (action === "snap_point" && Array.isArray(doubt.suggestion.point) && doubt.suggestion.point.length === 2) {
      const round = (x) => Math.round(x * 10) / 10;
      this.saving = true;
      this.dispatchEvent(new CustomEvent("ball-change", { detail: { frameId: this.#view.frame_id, point: doubt.suggestion.point.map(round) }, bubbles: true }));
      return true;
    }
    return false;
  }

  /** Exclude the view from the triangulation, or restore it (`excluded` forces one of the two). */
  toggleExclusion(excluded = null) {
    if (this.#saving || this.#drag) return false;
    const now = Boolean(this.#view.review?.excluded);
    const want = excluded === null ? !now : excluded;
    if (want === now) return false;
    this.saving = true;
    this.dispatchEvent(new CustomEvent("exclusion-request", { detail: { frameId: this.#view.frame_id, excluded: want }, bubbles: true }));
    return true;
  }

  /** A label placed from a doubt's suggestion, not confirmed by a person yet (the placement Enter confirms). */
  get pendingPlacement() {
    const ball = this.#view?.ball || {};
    return Boolean(ball.kind && ball.provenance);
  }

  /** Confirm a pending placement: send the same label as a person's (no provenance). False when none. */
  confirmPlacement() {
    const ball = this.#view?.ball || {};
    if (this.#saving || this.#drag || !this.pendingPlacement) return false;
    this.saving = true;
    this.dispatchEvent(new CustomEvent("ball-change", {
      detail: ball.kind === "box" ? { frameId: this.#view.frame_id, box: ball.box } : { frameId: this.#view.frame_id, point: ball.point },
      bubbles: true }));
    return true;
  }

  /** Where a zoom should centre this view (image pixels): on the box or point the other views agree on when a
   * doubt accuses its ball label and offers one (the real ball, not the doubted label), else null. */
  get suggestedCentre() {
    for (const d of this.#ctx.doubts || []) {
      if (!d.accuses_label || !d.suggestion) continue;
      if (validBox(d.suggestion.box)) return boxCentre(d.suggestion.box);
      if (validPoint(d.suggestion.point)) return d.suggestion.point;
    }
    return null;
  }

  /** Put back the label as imported, before any edit. */
  restoreLabel() {
    const ball = this.#view.ball || {};
    if (this.#saving || this.#drag || !ball.edited) return false;
    const detail = { frameId: this.#view.frame_id };
    if (validBox(ball.original_box)) detail.box = ball.original_box;
    else if (validPoint(ball.original_point)) detail.point = ball.original_point;
    else return false;
    this.saving = true;
    this.dispatchEvent(new CustomEvent("ball-change", { detail, bubbles: true }));
    return true;
  }

  /** Save now a keyboard edit still waiting for its pause (before a decision or moving on). */
  flush() {
    if (this.#nudgeTimer === null) return;
    clearTimeout(this.#nudgeTimer);
    this.#nudgeTimer = null;
    if (this.#live && !this.#saving) this.#commit();
  }

  /** Keyboard editing: move by (dx, dy) and grow every side by `grow` image pixels; saved after a pause. */
  nudge(dx, dy, grow = 0) {
    if (this.#saving || this.#drag) return false;
    const label = this.#currentLabel();
    if (!label) return false;
    const v = this.#view;
    if (label.box) {
      const b = label.box;
      if (b[2] - b[0] + 2 * grow < MIN_BOX || b[3] - b[1] + 2 * grow < MIN_BOX) return false;
      this.#live = { box: [b[0] + dx - grow, b[1] + dy - grow, b[2] + dx + grow, b[3] + dy + grow] };
    } else {
      this.#live = { point: [clamp(label.point[0] + dx, 0, v.width), clamp(label.point[1] + dy, 0, v.height)] };
    }
    this.#zoomWindow();
    this.#drawOverlays();
    clearTimeout(this.#nudgeTimer);
    this.#nudgeTimer = setTimeout(() => {
      this.#nudgeTimer = null;
      this.#commit();
    }, 450);
    return true;
  }
}

customElements.define("v3d-view", ViewPanel);
