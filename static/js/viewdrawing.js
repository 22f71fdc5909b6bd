// Drawing one view into an SVG whose viewBox is the image's pixel frame: the frame (or a blank canvas of its
// size while the image loads or when it is missing), the projected pitch lines, the annotated field lines
// (drawn by the view's line editor), the players' foot points a camera placed by its players was fitted to, the imported, optimised, precise and suggested boxes, the epipolar
// segments of the view's doubts, the ball label with its grab areas, and the reprojected 3D ball. Marks keep
// their screen size at any zoom (`scale`). Also where the zoomed inset around the ball looks (ballWindow).

import { svg, fmt, isNum } from "./format.js";
import { pinsOf } from "./comments.js";
import { FIX_KEY, boxCentre, sameBox, validBox, validPoint } from "./viewfacts.js";
import { DETECTOR_KINDS } from "./words.js";

/** The inset's window around the view's ball, [x, y, side] in image pixels (a square at least 72 px, six
 * times the ball's size, within the frame): centred on the ball label, else the reprojected 3D ball, else
 * the optimised box; null when the view has none of them. */
export function ballWindow(v) {
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
  return [centre[0] - side / 2, centre[1] - side / 2, side];
}

/** Draw `view` (system-view JSON) and its overlay into `root` (the frame's SVG when `isMain`, else the zoomed
 * inset). `scale`: screen pixels per image pixel; `imageState`: "loading" | "loaded" | "missing"; `lines`: the
 * view's line editor (lineseditor.js); `doubts`: the system's doubts naming this view; `label`: the ball label
 * shown ({box} or {point}, a drag's live one included; null: none); `grab(event, root, mode)`: a pointer
 * pressed on the label ("move", "resize" or "point"). */
export function drawView(root, { view: v, scale, isMain, imageState, lines, doubts, label, grab }) {
  const s = 1 / scale; // one screen pixel, in image pixels
  const nodes = [];
  if (imageState === "loaded") {
    nodes.push(svg("image", { href: v.image_url, x: 0, y: 0, width: v.width, height: v.height, preserveAspectRatio: "none" }));
  } else {
    nodes.push(svg("rect", { x: 0, y: 0, width: v.width, height: v.height, fill: "#101317" }));
    if (imageState === "loading" && isMain) {
      nodes.push(svg("text", { x: 8 * s, y: 18 * s, class: "nodata", "font-size": 11 * s, text: "loading image…" }));
    } else if (imageState !== "loading" && isMain) {
      // said plainly in the middle of the canvas: the labels and lines are drawn on nothing
      const size = Math.min(v.width / 8, 26 * s);
      nodes.push(svg("text", { x: v.width / 2, y: v.height / 2, class: "no-image", "text-anchor": "middle",
        "font-size": size, "data-testid": "no-image", text: v.image_url ? "no image (it could not be read)" : "no image" }));
      const note = v.image_url ? "its labels, drawn without their picture" : "labels only: this dataset has no pictures";
      nodes.push(svg("text", { x: v.width / 2, y: v.height / 2 + 1.5 * size, class: "no-image-note", "text-anchor": "middle",
        "font-size": Math.min(size * 0.5, v.width / (0.62 * note.length)), text: note }));
    }
  }
  const g = svg("g", { "data-testid": isMain ? "overlay" : "zoom-overlay" });
  for (const line of lines.pitchLines()) { // a drag's preview camera while a line point moves
    if (!line.points || line.points.length < 2) continue;
    g.append(svg("polyline", { class: "pitch", points: line.points.map((p) => p.join(",")).join(" ") },
      svg("title", { text: `projected: ${line.class}` })));
  }
  lines.drawLines(g, s, isMain);
  const feet = ((v.calibration || {}).players || {}).feet;
  if (Array.isArray(feet)) { // a camera the players placed: the foot points it was fitted to, small diamonds, and the
    for (const p of feet) { // head point of a player whose feet the image cuts, a small triangle pointing down
      if (!validPoint(p.px)) continue;
      const [x, y] = p.px, r = 4 * s;
      const head = p.point === "head";
      const d = head ? `M${x} ${y + r} L${x + r} ${y - r} L${x - r} ${y - r} Z`
        : `M${x} ${y - r} L${x + r} ${y} L${x} ${y + r} L${x - r} ${y} Z`;
      g.append(svg("path", { class: head ? "player-head" : "player-foot", d,
        "data-testid": isMain ? (head ? "player-head" : "player-foot") : null },
        svg("title", { text: head ? `${p.class} ${p.id}: head point the camera was fitted to (the image cuts its feet)`
          : `${p.class} ${p.id}: foot point the camera was fitted to` })));
    }
  }
  const ball = v.ball || {};
  if (ball.edited && validBox(ball.original_box) && !(ball.kind === "box" && sameBox(ball.original_box, ball.box))) {
    g.append(rect(ball.original_box, "box-prev", "imported box (before edits)"));
  }
  const opt = v.optimised_box;
  if (opt && validBox(opt.box)) {
    g.append(rect(opt.box, "halo"));
    g.append(rect(opt.box, "box-opt", `optimised box, d = ${fmt(opt.d_px, 1)} px`, "box-opt"));
  }
  if (validBox(v.precise_box)) { // the paper's Fig. 4: the reference Table 1 scores the boxes against
    g.append(rect(v.precise_box, "box-precise", "precise box (Table 1 reference)", isMain ? "precise-box" : null));
  }
  for (const d of doubts) {
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
      const det = DETECTOR_KINDS.includes(d.kind) ? (d.evidence || {}) : null;
      if (det) { // a detector's box, checked by the other views: its own colour, with its detector and score
        g.append(rect(sb, "box-detected", `${det.detector} found the ball here, score ${fmt(det.score, 2)} (${FIX_KEY.snap_box} places its box)`,
          isMain ? "detected-box" : null));
        g.append(svg("text", { class: "det-score", x: sb[0], y: sb[1] - 4 * s, "font-size": 12 * s, text: `${det.detector} ${fmt(det.score, 2)}` }));
      } else {
        g.append(rect(sb, "box-sugg", `suggested box (${FIX_KEY.snap_box} snaps the ball label to it)`, isMain ? "suggested-box" : null));
      }
    }
  }
  if (label && label.box) {
    const b = label.box;
    g.append(rect(b, "halo"));
    g.append(rect(b, "box-orig", "annotated ball box (drag to move, corner to resize)", "box-orig"));
    // hit area at least 18 screen pixels wide, so a 3-pixel box can be grabbed
    const [cx, cy] = boxCentre(b);
    const hw = Math.max((b[2] - b[0]) / 2, 9 * s), hh = Math.max((b[3] - b[1]) / 2, 9 * s);
    const hit = svg("rect", { class: "hit", x: cx - hw, y: cy - hh, width: 2 * hw, height: 2 * hh, "data-testid": isMain ? "ball-hit" : "zoom-ball-hit" });
    hit.addEventListener("pointerdown", (e) => grab(e, root, "move"));
    g.append(hit);
    const hs = 8 * s;
    const handle = svg("rect", { class: "handle", x: b[2] - hs / 2 + (isMain ? hw - (b[2] - b[0]) / 2 : 0), y: b[3] - hs / 2 + (isMain ? hh - (b[3] - b[1]) / 2 : 0),
      width: hs, height: hs, "data-testid": isMain ? "ball-handle" : "zoom-ball-handle" });
    handle.addEventListener("pointerdown", (e) => grab(e, root, "resize"));
    g.append(handle);
  } else if (label && label.point) {
    const p = label.point;
    const dot = svg("circle", { class: "point-orig", cx: p[0], cy: p[1], r: 4 * s, "data-testid": isMain ? "ball-point" : "zoom-ball-point" },
      svg("title", { text: "annotated ball point (drag to move)" }));
    dot.style.cursor = "move";
    dot.addEventListener("pointerdown", (e) => grab(e, root, "point"));
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
  if (isMain) {
    for (const c of pinsOf(v.frame_id)) { // the reviewers' comments at their points (comments.js)
      if (!c.point) continue;
      g.append(svg("g", { class: `comment-pin${c.resolved ? " resolved" : ""}`, "data-testid": "review-comment-pin", "data-id": String(c.id) },
        svg("circle", { cx: c.point[0], cy: c.point[1], r: 9 * s }),
        svg("text", { x: c.point[0], y: c.point[1] + 4 * s, "font-size": 11 * s, "text-anchor": "middle", text: String(c.number) }),
        svg("title", { text: `${c.number}. ${c.author}: ${c.text}${c.resolved ? " (resolved)" : ""}` })));
    }
  }
  if (isMain) lines.drawHandles(g, root, s); // above the ball's box, in edit mode
  nodes.push(g);
  root.replaceChildren(...nodes);
}

/** An SVG rectangle of box `b` ([x1, y1, x2, y2], image pixels) with class `cls`, a tooltip and a test id. */
function rect(b, cls, title, testid) {
  const r = svg("rect", { class: cls, x: b[0], y: b[1], width: b[2] - b[0], height: b[3] - b[1], "data-testid": testid });
  if (title) r.append(svg("title", { text: title }));
  return r;
}
