// <v3d-trajectory>: an ISSIA sequence's ball over time (GET /api/games/{id}/trajectory), drawn in SVG.
// Three panels against the frame index: x, y and the height above the grass (-z), world metres.
// Dots: the frame's own triangulation (ball_3D); line: the fitted trajectory (ball_3D_smoothed);
// red ticks: frames whose labels break the trajectory (ball_off_consensus); blue line: the current
// frame. The scrubber (a range input) and a click on a panel pick a frame: the element dispatches
// "frame-select" with {systemId, frameIndex} and the page moves to that frame's system.

import { svg, el, isNum } from "./format.js";

const PANELS = [
  { key: "x", label: "x (m)", get: (p) => p[0] },
  { key: "y", label: "y (m)", get: (p) => p[1] },
  { key: "h", label: "height (m)", get: (p) => -p[2] },
];
const W = 300, H = 70, PAD_L = 34, PAD_R = 6, PAD_T = 6, PAD_B = 6;

function finite(p) {
  return Array.isArray(p) && p.length === 3 && p.every(isNum);
}

export class TrajectoryView extends HTMLElement {
  #data = null;
  #current = null;

  /** {trajectory: TrajectoryOut, current: frame index}. */
  set data(value) {
    this.#data = value?.trajectory || null;
    this.#current = value?.current ?? null;
    this.render();
  }

  frameAt(index) {
    return (this.#data?.frames || []).find((f) => f.frame_index === index) || null;
  }

  select(index) {
    const f = this.frameAt(index);
    if (!f || index === this.#current) return;
    this.dispatchEvent(new CustomEvent("frame-select", { detail: { systemId: f.system_id, frameIndex: index }, bubbles: true }));
  }

  render() {
    const t = this.#data;
    if (!t || !t.frames.length) {
      this.replaceChildren();
      return;
    }
    const frames = t.frames;
    const f0 = frames[0].frame_index, f1 = frames[frames.length - 1].frame_index;
    const sx = (f) => PAD_L + ((f - f0) / Math.max(f1 - f0, 1)) * (W - PAD_L - PAD_R);
    const children = [];
    for (const panel of PANELS) {
      const vals = [];
      for (const f of frames) {
        for (const p of [f.ball3d, f.ball3d_smoothed]) if (finite(p)) vals.push(panel.get(p));
      }
      let lo = Math.min(...vals), hi = Math.max(...vals);
      if (!vals.length) { lo = 0; hi = 1; }
      if (hi - lo < 0.5) { const m = (hi + lo) / 2; lo = m - 0.25; hi = m + 0.25; }
      const sy = (v) => PAD_T + (1 - (v - lo) / (hi - lo)) * (H - PAD_T - PAD_B);
      const root = svg("svg", { viewBox: `0 0 ${W} ${H}`, class: "traj-panel", "data-testid": `trajectory-${panel.key}`,
        role: "img", "aria-label": `${panel.label} against the frame index` });
      root.append(svg("rect", { class: "traj-bg", x: PAD_L, y: PAD_T, width: W - PAD_L - PAD_R, height: H - PAD_T - PAD_B }));
      root.append(svg("text", { class: "traj-axis", x: 2, y: PAD_T + 8, text: hi.toFixed(1) }));
      root.append(svg("text", { class: "traj-axis", x: 2, y: H - PAD_B, text: lo.toFixed(1) }));
      root.append(svg("text", { class: "traj-name", x: PAD_L + 3, y: PAD_T + 9, text: panel.label }));
      for (const f of frames) {
        if (f.flagged.length) {
          root.append(svg("line", { class: "traj-flag", "data-testid": "trajectory-flag", x1: sx(f.frame_index), x2: sx(f.frame_index),
            y1: PAD_T, y2: H - PAD_B }, svg("title", { text: `frame ${f.frame_index}: ${f.flagged.join(", ")} break the trajectory` })));
        }
      }
      // the fitted trajectory, broken where there is no position
      let d = "", pen = false;
      for (const f of frames) {
        if (finite(f.ball3d_smoothed)) {
          d += `${pen ? "L" : "M"}${sx(f.frame_index).toFixed(2)} ${sy(panel.get(f.ball3d_smoothed)).toFixed(2)} `;
          pen = true;
        } else pen = false;
      }
      root.append(svg("path", { class: "traj-fit", d, "data-testid": "trajectory-fit" }));
      for (const f of frames) {
        if (finite(f.ball3d)) {
          root.append(svg("circle", { class: "traj-obs", cx: sx(f.frame_index), cy: sy(panel.get(f.ball3d)), r: 1.3 }));
        }
      }
      if (this.#current !== null) {
        root.append(svg("line", { class: "traj-current", "data-testid": "trajectory-current", x1: sx(this.#current), x2: sx(this.#current),
          y1: PAD_T, y2: H - PAD_B }));
      }
      root.addEventListener("click", (e) => {
        const box = root.getBoundingClientRect();
        const x = ((e.clientX - box.left) / box.width) * W;
        const f = Math.round(f0 + ((x - PAD_L) / (W - PAD_L - PAD_R)) * (f1 - f0));
        this.select(Math.min(Math.max(f, f0), f1));
      });
      children.push(root);
    }
    const cur = this.frameAt(this.#current);
    const scrub = el("input", { type: "range", min: f0, max: f1, step: 1, value: this.#current ?? f0,
      "data-testid": "trajectory-scrubber", "aria-label": "frame index" });
    const label = el("span", { class: "mono", "data-testid": "trajectory-frame" }, `frame ${this.#current ?? "—"}`);
    scrub.addEventListener("input", () => { label.textContent = `frame ${scrub.value}`; });
    scrub.addEventListener("change", () => {
      scrub.blur(); // the page's keys (j / k, "," / ".") work again at once
      this.select(Number(scrub.value));
    });
    const info = el("div", { class: "muted traj-info", "data-testid": "trajectory-info" },
      cur ? `${cur.source || "no position"}; kept ${cur.cam_list.join(", ") || "—"}${cur.flagged.length ? `; off the trajectory: ${cur.flagged.join(", ")}` : ""}` : "");
    const legend = el("div", { class: "muted traj-legend" },
      el("span", { class: "traj-key obs" }, "● ball_3D (per frame)"), " ",
      el("span", { class: "traj-key fit" }, "— fitted"), " ",
      el("span", { class: "traj-key flag" }, "| flagged label"), " ",
      el("span", { class: "traj-key cur" }, "| this frame"));
    this.replaceChildren(...children, el("div", { class: "traj-scrub" }, scrub, label), info, legend);
  }
}

customElements.define("v3d-trajectory", TrajectoryView);
