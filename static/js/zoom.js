// Synchronised zoom and pan of the system page's views. One state for the page: a zoom factor z
// (1 = the whole frame) and a pan, the offset of the window's centre from the ball as fractions of the image's
// width and height, so views of any resolution move alike. Every view shows the window of its own image
// centred on its ball plus the pan: where a doubt accuses the view's ball label, the box the other views agree
// on (the panel's `suggestedCentre`: the real ball is on screen, not the doubted label); else the ball label's
// centre (box or point), else the 3D ball's reprojection, else the optimised box's centre, else the image's
// centre; the window is kept inside the image.
//
// Crisp at any zoom: the window is the frame SVG's viewBox (image pixels), so the overlay is vector-drawn
// again at the new scale (the panel redraws its marks in screen pixels, strokes do not scale) and the frame
// image is drawn pixelated once an image pixel covers 3 screen pixels. No CSS scaling of a raster.
//
// The state is kept in sessionStorage (`v3d.zoom`): moving to the next system keeps the zoom and pan.
// Mouse: the wheel over a view zooms every view on its ball; a middle-button drag pans them all.
// Keys (the page's key table): > / < zoom in / out, 0 the whole frame, Shift+I / J / K / L pan.

import { el, isNum } from "./format.js";

const STORAGE_KEY = "v3d.zoom";
export const MIN_ZOOM = 1;
export const MAX_ZOOM = 64;
const STEP = 1.5; // zoom factor of one key press or wheel notch
const PAN_STEP = 0.25; // a pan key moves a quarter of the window
const PIXELATED_AT = 3; // screen pixels per image pixel from which the frame is drawn pixelated

const valid = (p) => Array.isArray(p) && p.length === 2 && p.every(isNum);
const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));

/** Where a view's ball is, image pixels: the label's centre, else the 3D ball's reprojection, else the
 * optimised box's centre; null when none. */
export function ballCentre(view) {
  const ball = view.ball || {};
  const boxCentre = (b) => (Array.isArray(b) && b.length === 4 && b.every(isNum) ? [(b[0] + b[2]) / 2, (b[1] + b[3]) / 2] : null);
  if (ball.kind === "box" && boxCentre(ball.box)) return boxCentre(ball.box);
  if (ball.kind === "point" && valid(ball.point)) return ball.point;
  if (valid(view.reprojected_ball)) return view.reprojected_ball;
  return boxCentre(view.optimised_box?.box);
}

/** The window [x, y, w, h] (image pixels) a view of `width` x `height` shows at zoom `z` and `pan`
 * ([fx, fy], fractions of the image) around `centre` (null: the image's centre); inside the image. */
export function viewWindow(width, height, centre, z, pan) {
  if (z <= MIN_ZOOM) return [0, 0, width, height];
  const w = width / z, h = height / z;
  const c = centre && valid(centre) ? centre : [width / 2, height / 2];
  const cx = clamp(c[0] + pan[0] * width, w / 2, width - w / 2);
  const cy = clamp(c[1] + pan[1] * height, h / 2, height - h / 2);
  return [cx - w / 2, cy - h / 2, w, h];
}

export class ZoomSync {
  /** `views`: the page's views container (its children are <v3d-view> panels); `before`: the element the
   * zoom's bar is put in front of. */
  constructor(views, before) {
    this.views = views;
    this.state = readState();
    this.bar = el("div", { class: "zoom-bar", "data-testid": "zoom-bar" });
    before.before(this.bar);
    this.drawBar();
    views.addEventListener("wheel", (e) => this.onWheel(e), { passive: false });
    views.addEventListener("pointerdown", (e) => this.onPointerDown(e), true);
    views.addEventListener("auxclick", (e) => { if (e.button === 1) e.preventDefault(); });
  }

  get zoom() {
    return this.state.z;
  }

  /** Show the state in every panel (after a render: each panel's rebuild resets its viewBox). */
  apply() {
    for (const panel of this.views.children) this.applyTo(panel);
    this.drawBar();
  }

  /** Show the state in one panel: its frame SVG's viewBox, then the panel redraws its marks at that scale. */
  applyTo(panel) {
    const view = panel.view;
    const frame = panel.querySelector("[data-testid=view-svg]");
    if (!view || !frame) return;
    // a view whose ball label is doubted centres on the ball the other views agree on (the real ball)
    const win = viewWindow(view.width, view.height, panel.suggestedCentre || ballCentre(view), this.state.z, this.state.pan);
    frame.setAttribute("viewBox", win.map((x) => Number(x.toFixed(3))).join(" "));
    frame.dataset.zoom = String(this.state.z);
    const shown = frame.getBoundingClientRect().width || 560;
    frame.classList.toggle("pixelated", shown / win[2] >= PIXELATED_AT);
    panel.redraw?.();
  }

  set(z, pan = this.state.pan) {
    const zoom = clamp(z, MIN_ZOOM, MAX_ZOOM);
    // at the whole frame there is nothing to pan; a pan never takes the ball more than half a frame away
    this.state = { z: zoom, pan: zoom <= MIN_ZOOM ? [0, 0] : pan.map((p) => clamp(p, -0.5, 0.5)) };
    writeState(this.state);
    this.apply();
    return true;
  }

  zoomBy(factor) {
    const z = this.state.z * factor;
    return this.set(Math.abs(z - 1) < 1e-6 ? 1 : z); // in then out again is the whole frame
  }

  /** Pan by (dx, dy) windows (a key: a quarter of the window). */
  panBy(dx, dy) {
    if (this.state.z <= MIN_ZOOM) return false;
    const [px, py] = this.state.pan;
    return this.set(this.state.z, [px + dx / this.state.z, py + dy / this.state.z]);
  }

  reset() {
    return this.set(1, [0, 0]);
  }

  drawBar() {
    const z = this.state.z;
    this.bar.replaceChildren(
      el("span", { class: "muted" }, "zoom"),
      el("button", { type: "button", "data-testid": "zoom-out", title: "Zoom out (<)", onclick: () => this.zoomBy(1 / STEP) }, "−"),
      el("span", { class: "mono", "data-testid": "zoom-level", title: "zoom of every view, around its ball" }, `×${fmtZoom(z)}`),
      el("button", { type: "button", "data-testid": "zoom-in", title: "Zoom in (>)", onclick: () => this.zoomBy(STEP) }, "+"),
      el("button", { type: "button", "data-testid": "zoom-reset", title: "The whole frames (0)", disabled: z <= MIN_ZOOM,
        onclick: () => this.reset() }, "reset"));
    this.bar.title = "Every view zooms on its ball (its reprojection where it has no label): wheel or > / <, "
      + "0 for the whole frames; middle-drag or Shift+I/J/K/L pans them all. Kept when moving to another system.";
  }

  onWheel(e) {
    if (!e.target.closest?.("[data-testid=view-svg]") || e.ctrlKey) return;
    e.preventDefault();
    this.zoomBy(e.deltaY < 0 ? STEP : 1 / STEP);
  }

  /** A middle-button drag on a view pans every view by the same fraction of its image. */
  onPointerDown(e) {
    const frame = e.target.closest?.("[data-testid=view-svg]");
    if (!frame || e.button !== 1 || this.state.z <= MIN_ZOOM) return;
    e.preventDefault();
    e.stopPropagation();
    const rect = frame.getBoundingClientRect();
    const start = { x: e.clientX, y: e.clientY, pan: [...this.state.pan] };
    const move = (m) => {
      // the window spans rect.width screen px and 1/z of the image
      const fx = -(m.clientX - start.x) / rect.width / this.state.z;
      const fy = -(m.clientY - start.y) / rect.height / this.state.z;
      this.set(this.state.z, [start.pan[0] + fx, start.pan[1] + fy]);
    };
    const up = () => {
      frame.removeEventListener("pointermove", move);
      frame.removeEventListener("pointerup", up);
      frame.removeEventListener("pointercancel", up);
    };
    frame.setPointerCapture(e.pointerId);
    frame.addEventListener("pointermove", move);
    frame.addEventListener("pointerup", up);
    frame.addEventListener("pointercancel", up);
  }

  /** The key-table entries (keys.js). */
  keyEntries() {
    const pan = { I: [0, -PAN_STEP], K: [0, PAN_STEP], J: [-PAN_STEP, 0], L: [PAN_STEP, 0] };
    return [
      { keys: [">", "<"], does: "zoom every view in / out on its ball (its reprojection where it has no label)",
        run: (e) => this.zoomBy(e.key === ">" ? STEP : 1 / STEP) },
      { keys: ["0"], does: "whole frames (no zoom)", run: () => this.reset() },
      { keys: ["I", "J", "K", "L"], show: ["⇧I", "⇧J", "⇧K", "⇧L"], does: "pan every zoomed view up / left / down / right",
        run: (e) => this.panBy(...pan[e.key]) },
    ];
  }
}

function fmtZoom(z) {
  return z >= 10 ? z.toFixed(0) : String(Number(z.toFixed(2)));
}

function readState() {
  try {
    const s = JSON.parse(sessionStorage.getItem(STORAGE_KEY) || "null");
    if (s && isNum(s.z) && valid(s.pan)) {
      return { z: clamp(s.z, MIN_ZOOM, MAX_ZOOM), pan: s.pan.map((p) => clamp(p, -0.5, 0.5)) };
    }
  } catch {
    // a state another version wrote: start from the whole frame
  }
  return { z: 1, pan: [0, 0] };
}

function writeState(state) {
  try {
    sessionStorage.setItem(STORAGE_KEY, JSON.stringify(state));
  } catch {
    // storage refused (private mode): the zoom still works, for this page only
  }
}
