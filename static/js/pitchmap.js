// <v3d-pitch-map>: top-down SVG of the pitch (SoccerNet world frame, metres, x to the right, y down the
// screen so "Side line top" (y = -34) is at the top), the camera centres of the views and the 3D ball;
// for an ISSIA sequence also the ball's fitted track (``track``: [[x, y, z], ...]).

import { svg, isNum } from "./format.js";

// Pitch model dimensions (method.md section 3).
const L = 105, W = 68, HL = L / 2, HW = W / 2;
const PA_L = 16.5, PA_W = 40.32, GA_L = 5.5, GA_W = 18.32, R = 9.15, SPOT = 11, GOAL_W = 7.32;

function arcPath(cx, cy, r, a0, a1) {
  const x0 = cx + r * Math.cos(a0), y0 = cy + r * Math.sin(a0);
  const x1 = cx + r * Math.cos(a1), y1 = cy + r * Math.sin(a1);
  const large = Math.abs(a1 - a0) > Math.PI ? 1 : 0;
  return `M${x0} ${y0} A${r} ${r} 0 ${large} 1 ${x1} ${y1}`;
}

/** The pitch markings as SVG path data (ground plane, metres). */
function pitchPaths() {
  const d = [];
  d.push(`M${-HL} ${-HW} H${HL} V${HW} H${-HL} Z`); // touch and goal lines
  d.push(`M0 ${-HW} V${HW}`); // halfway line
  d.push(arcPath(0, 0, R, 0, Math.PI) + " " + arcPath(0, 0, R, Math.PI, 2 * Math.PI));
  const arcA = Math.acos((PA_L - SPOT) / R); // penalty arc half-angle
  for (const s of [-1, 1]) {
    const gx = s * HL;
    d.push(`M${gx} ${-PA_W / 2} H${gx - s * PA_L} V${PA_W / 2} H${gx}`);
    d.push(`M${gx} ${-GA_W / 2} H${gx - s * GA_L} V${GA_W / 2} H${gx}`);
    const mx = gx - s * SPOT;
    // the part of the circle around the penalty mark outside the penalty area
    if (s < 0) d.push(arcPath(mx, 0, R, -arcA, arcA));
    else d.push(arcPath(mx, 0, R, Math.PI - arcA, Math.PI + arcA));
    d.push(`M${gx} ${-GOAL_W / 2} H${gx + s * 2} V${GOAL_W / 2} H${gx}`); // goal (drawn 2 m deep)
  }
  return d;
}

export class PitchMap extends HTMLElement {
  #data = null;

  set data(value) {
    this.#data = value;
    this.render();
  }

  get data() {
    return this.#data;
  }

  render() {
    const { ball3d = null, cameras = [], track = [] } = this.#data || {};
    const path = track.filter((p) => Array.isArray(p) && p.length >= 2 && isNum(p[0]) && isNum(p[1]));
    const hasBall = Array.isArray(ball3d) && ball3d.every(isNum);
    const placed = cameras.filter((c) => Array.isArray(c.position) && c.position.every(isNum));
    let minX = -HL - 4, maxX = HL + 4, minY = -HW - 4, maxY = HW + 4;
    const include = (x, y, m) => {
      minX = Math.min(minX, x - m);
      maxX = Math.max(maxX, x + m);
      minY = Math.min(minY, y - m);
      maxY = Math.max(maxY, y + m);
    };
    for (const c of placed) include(c.position[0], c.position[1], 5);
    if (hasBall) include(ball3d[0], ball3d[1], 3);
    // label anchors: near-duplicate viewpoints get their labels stacked instead of overprinted
    const labels = [];
    for (const c of placed) {
      const [x, y] = c.position;
      let ly = y + 1.1;
      while (labels.some(([ax, ay]) => Math.abs(ax - x) < 8 && Math.abs(ay - ly) < 3.4)) ly += 3.6;
      labels.push([x, ly]);
      include(x, ly, 2.5);
    }

    const root = svg("svg", {
      viewBox: `${minX} ${minY} ${maxX - minX} ${maxY - minY}`,
      role: "img",
      "aria-label": "top-down pitch map with camera positions and the 3D ball",
      "data-testid": "pitch-map-svg",
    });
    root.append(svg("rect", { class: "grass", x: -HL - 3, y: -HW - 3, width: L + 6, height: W + 6, rx: 1 }));
    for (const d of pitchPaths()) root.append(svg("path", { class: "line", d }));
    if (path.length > 1) { // an ISSIA sequence's fitted track (ball_3D_smoothed), start to end
      const d = path.map((p, i) => `${i ? "L" : "M"}${p[0].toFixed(2)} ${p[1].toFixed(2)}`).join(" ");
      root.append(svg("path", { class: "track", d, "data-testid": "pitch-track" },
        svg("title", { text: `the ball's fitted track over ${path.length} frames` })));
    }
    placed.forEach((c, i) => {
      const [x, y, z] = c.position;
      if (hasBall) {
        root.append(svg("line", { class: "ray", x1: x, y1: y, x2: ball3d[0], y2: ball3d[1], stroke: c.colour }));
      }
      const g = svg("g", { "data-testid": "pitch-camera", "data-view": c.label });
      g.append(svg("title", { text: `${c.label} ${c.name}: camera at x ${x.toFixed(1)} m, y ${y.toFixed(1)} m, ${(-z).toFixed(1)} m high` }));
      g.append(svg("circle", { class: "cam", cx: x, cy: y, r: 1.6, fill: c.colour }));
      const right = x < maxX - 12;
      g.append(svg("text", { class: "cam-label", x: right ? x + 2.4 : x - 2.4, y: labels[i][1], "text-anchor": right ? "start" : "end", text: c.label }));
      root.append(g);
    });
    if (hasBall) {
      const g = svg("g", { "data-testid": "pitch-ball" });
      g.append(svg("title", { text: `3D ball: x ${ball3d[0].toFixed(2)} m, y ${ball3d[1].toFixed(2)} m, ${(-ball3d[2]).toFixed(2)} m above the ground` }));
      g.append(svg("circle", { class: "ball", cx: ball3d[0], cy: ball3d[1], r: 1.2 }));
      root.append(g);
    }
    this.replaceChildren(root);
  }
}

customElements.define("v3d-pitch-map", PitchMap);
