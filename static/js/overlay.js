// <v3d-view>: the panel of one view of a multi-view system. The frame (or a blank canvas of the frame's size
// when the image is unavailable) with an SVG overlay in image pixels, drawn by viewdrawing.js (projected pitch
// lines, field lines, the ball's boxes, the reprojected 3D ball); a zoomed inset around the ball makes a
// 10-pixel box editable. The panel holds the view's state (its JSON and context, the image's loading, saving,
// selection), builds its DOM (header, doubts bar, frame, line-editor bar, inset, facts: viewfacts.js), and
// sends the page the writes it asks for: "ball-change" {frameId, box} or {frameId, point} (its ball label,
// edited by balledit.js, or a doubt's fix), "exclusion-request" and "mirror-request"; the page saves them and
// sets the recomputed view back. Its field lines are edited by lineseditor.js.
//
// The SVG viewBox is the image's pixel frame, so drawings and pointer positions map exactly at any display
// size (pointer positions go through getScreenCTM()).

import { el, svg, viewColour, STATUS_LABEL } from "./format.js";
import { chipClass } from "./words.js";
import { LineEditor } from "./lineseditor.js";
import { BallEditor } from "./balledit.js";
import { ballWindow, drawView } from "./viewdrawing.js";
import { getPitchLines } from "./api.js";
import { working } from "./busy.js";
import { FIX_KEY, FIX_LABEL, boxCentre, isMirrorFlagged, notes, validBox, validPoint, viewDoubtItems, viewFacts } from "./viewfacts.js";

const ZOOM_PX = 150; // displayed size of the zoom inset

export class ViewPanel extends HTMLElement {
  #view = null;
  #ctx = { index: 0, tau: null, rule: null, referenceWidth: null, viewCount: 0, doubts: [] };
  #imageState = "loading"; // loading | loaded | missing
  #imageUrl = null;
  #redrawQueued = false; // a redrawSoon() waits for the next animation frame
  #zoomBox = null; // [x, y, size] of the inset, frozen while dragging
  #saving = false;
  #selected = false;
  #resizeObserver = null;
  #built = false;
  lines = new LineEditor(this); // the field-line editor of this view (lineseditor.js)
  ball = new BallEditor(this); // the editor of its ball label (balledit.js)

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
    this.ball.forget();
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
    this.ball.forget();
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
    const arrived = working("image"); // the page's work until the frame is drawn or known missing (busy.js)
    probe.onload = () => {
      this.#imageSettled(url, "loaded");
      arrived();
    };
    probe.onerror = () => {
      this.#imageSettled(url, "missing");
      arrived();
    };
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
        if ((!this.ball.label() || this.ball.dragging) && !this.lines.editing) this.ball.grab(e, frameSvg, "draw");
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
        excluded ? el("span", { class: chipClass("note", "excluded"), "data-testid": "view-excluded", title: "excluded from the triangulation by a reviewer (x to restore)" }, "excluded") : null,
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
  /** The zoomed inset's window around the ball ([x, y, side], image pixels; null: no ball), frozen until the
   * next update. */
  #zoomWindow() {
    if (!this.#zoomBox) this.#zoomBox = ballWindow(this.#view);
    return this.#zoomBox;
  }

  /** Keep the zoomed inset where it is while the ball label is edited (balledit.js). */
  freezeZoom() {
    this.#zoomWindow();
  }

  #drawOverlays() {
    if (!this.#built || !this.#view) return;
    const v = this.#view;
    const frameSvg = this.querySelector("[data-testid=view-svg]");
    const zoomSvg = this.querySelector("[data-testid=view-zoom]");
    const width = frameSvg.getBoundingClientRect().width || 560;
    // the viewBox is the window shown (the whole frame, or a zoom: zoom.js): marks keep their screen size
    this.#draw(frameSvg, width / (frameSvg.viewBox.baseVal?.width || v.width), true);
    const zw = this.#zoomWindow();
    const zoomLabel = this.querySelector("[data-testid=zoom-label]");
    if (zw) {
      zoomSvg.setAttribute("viewBox", `${zw[0]} ${zw[1]} ${zw[2]} ${zw[2]}`);
      this.#draw(zoomSvg, ZOOM_PX / zw[2], false);
      zoomLabel.textContent = `ball ×${(ZOOM_PX / zw[2] / (width / v.width)).toFixed(1)}`;
    } else {
      zoomSvg.setAttribute("viewBox", `0 0 ${v.width} ${v.height}`);
      zoomSvg.replaceChildren(svg("text", { x: v.width / 2, y: v.height / 2, "text-anchor": "middle", class: "nodata",
        "font-size": v.width / 14, text: "no ball" }));
      zoomLabel.textContent = "";
    }
  }

  /** Draw the frame and overlay into `root` (viewdrawing.js); `scale` = screen pixels per image pixel. */
  #draw(root, scale, isMain) {
    drawView(root, { view: this.#view, scale, isMain, imageState: this.#imageState, lines: this.lines,
      doubts: this.#ctx.doubts || [], label: this.ball.label(), grab: (e, svgRoot, mode) => this.ball.grab(e, svgRoot, mode) });
  }

  // ----- what the view asks the page to write --------------------------------------------------
  /** Remove the ball label (the ball is not visible in this view). */
  removeLabel() {
    if (this.#saving || this.ball.dragging || !(this.#view.ball || {}).kind) return false;
    this.saving = true;
    this.dispatchEvent(new CustomEvent("ball-change", { detail: { frameId: this.#view.frame_id, box: null }, bubbles: true }));
    return true;
  }

  /** Ask the page to replace this view's field lines by their mirrored labelling (flagged views only). */
  requestMirror() {
    if (this.#saving || this.ball.dragging || !isMirrorFlagged(this.#view)) return false;
    this.saving = true;
    this.dispatchEvent(new CustomEvent("mirror-request", { detail: { frameId: this.#view.frame_id }, bubbles: true }));
    return true;
  }

  /** The first doubt of this view whose fix can be applied (a label-accusing one first); with `key`, only a fix
   * of that key (FIX_KEY: `s` snaps, `x` excludes, `m` mirrors). */
  fixableDoubt(key = null) {
    const ds = (this.#ctx.doubts || []).filter((d) => d.suggestion && FIX_LABEL[d.suggestion.action]
      && (!key || FIX_KEY[d.suggestion.action] === key));
    return ds.find((d) => d.accuses_label) || ds[0] || null;
  }

  /** Apply a doubt's fix: snap the ball label to the suggested box, exclude the view, or mirror its labels. */
  applyFix(doubt) {
    if (this.#saving || this.ball.dragging || !doubt || !doubt.suggestion) return false;
    const action = doubt.suggestion.action;
    if (action === "mirror_labels") return this.requestMirror();
    if (action === "exclude_view") return this.toggleExclusion(true);
    if (action === "snap_box" && validBox(doubt.suggestion.box)) {
      const round = (x) => Math.round(x * 10) / 10;
      this.saving = true;
      const provenance = ((doubt.suggestion.request || {}).body || {}).provenance; // the label keeps where it came from
      this.dispatchEvent(new CustomEvent("ball-change", { detail: { frameId: this.#view.frame_id, box: doubt.suggestion.box.map(round), provenance,
        said: provenance ? "ball snapped to the suggested box: Enter confirms it" : "ball snapped to the suggested box" }, bubbles: true }));
      return true;
    }
    if (action === "snap_point" && Array.isArray(doubt.suggestion.point) && doubt.suggestion.point.length === 2) {
      const round = (x) => Math.round(x * 10) / 10;
      this.saving = true;
      this.dispatchEvent(new CustomEvent("ball-change", { detail: { frameId: this.#view.frame_id, point: doubt.suggestion.point.map(round), said: "ball snapped to the suggested point" }, bubbles: true }));
      return true;
    }
    return false;
  }

  /** Exclude the view from the triangulation, or restore it (`excluded` forces one of the two). */
  toggleExclusion(excluded = null) {
    if (this.#saving || this.ball.dragging) return false;
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
    if (this.#saving || this.ball.dragging || !this.pendingPlacement) return false;
    this.saving = true;
    const said = "suggested ball confirmed: it counts for the 3D ball now";
    this.dispatchEvent(new CustomEvent("ball-change", {
      detail: ball.kind === "box" ? { frameId: this.#view.frame_id, box: ball.box, said } : { frameId: this.#view.frame_id, point: ball.point, said },
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
    if (this.#saving || this.ball.dragging || !ball.edited) return false;
    const detail = { frameId: this.#view.frame_id };
    if (validBox(ball.original_box)) detail.box = ball.original_box;
    else if (validPoint(ball.original_point)) detail.point = ball.original_point;
    else return false;
    detail.said = "ball restored to the imported label";
    this.saving = true;
    this.dispatchEvent(new CustomEvent("ball-change", { detail, bubbles: true }));
    return true;
  }
}

customElements.define("v3d-view", ViewPanel);
