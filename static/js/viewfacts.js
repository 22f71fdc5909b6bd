// A view's facts and doubts in words, for its <v3d-view> panel (overlay.js): the facts list (calibration and
// its flags, JaC at each stored gamma, the camera's uncertainty, the reprojection error against τ, the ball label,
// the optimised box, the view's actions), the doubts bar with each doubt's fix buttons, the notes; and the ball
// label's box and point helpers (image pixels) the panel's drawing shares. Pure DOM building from the system
// view's JSON: the panel passes itself for the buttons' actions.

import { el, fmt, fmtJac, isNum, errorClass } from "./format.js";
import { suggestedNote } from "./suggested.js";
import { DETECTOR_KINDS, chip, chipClass, doubtDrawing, word, tauText } from "./words.js";

/** The calibration's standard deviations as one line: "x/y/z m · pan/tilt/roll ° · f px". */
/** Below this (m) a position's standard deviation is that of a camera pinned to a known position, not a fit's. */
const PINNED_M = 0.005;

export function uncertaintyText(u) {
  const p = u.position_m || {};
  // a camera fitted at a known position (the rig's, a static camera's) has no doubt about where it stands: "0.00 m"
  // three times reads as a perfect fit, so say why it is nought
  const pinned = [p.x, p.y, p.z].every((v) => isNum(v) && Math.abs(v) < PINNED_M);
  const where = pinned ? "where: pinned to a known camera position"
    : `where x ${fmt(p.x, 2)}, y ${fmt(p.y, 2)}, z ${fmt(p.z, 2)} m`;
  return `${where} · aim pan ${fmt(u.pan_deg, 2)}°, tilt ${fmt(u.tilt_deg, 2)}°, roll ${fmt(u.roll_deg, 2)}° · zoom ${fmt(u.focal_px, 0)} px`;
}

export function boxCentre(b) {
  return [(b[0] + b[2]) / 2, (b[1] + b[3]) / 2];
}

export function validBox(b) {
  return Array.isArray(b) && b.length === 4 && b.every(isNum);
}

export function validPoint(p) {
  return Array.isArray(p) && p.length === 2 && p.every(isNum);
}

export function sameBox(a, b) {
  return validBox(a) && validBox(b) && a.every((v, i) => Math.abs(v - b[i]) < 0.05);
}

/** True when the server flags the view's labels as probably mirrored. */
export function isMirrorFlagged(view) {
  return (view.calibration || {}).probably_mirrored === true;
}

/** What the view's state says a reviewer should look at, besides the server's doubts (empty when
 * nothing): calibration problems and the server's "above tau" verdict (`error_above_tau`, the rule the
 * queue's "error > τ" count uses too). Label problems come from the server (`doubts`). */
export function notes(view, multiView = true) {
  const out = [];
  const cal = view.calibration || {};
  if (!cal.camera) out.push(cal.status ? `not calibrated (${cal.status})` : "not calibrated");
  else if (cal.admitted === false) out.push("calibration not admitted");
  if (cal.reason) out.push(cal.reason);
  if (view.review?.excluded) out.push("excluded from the 3D ball");
  else if (view.error_above_tau === true && multiView) out.push("reprojection error above τ");
  return out;
}

/** What a doubt's fix does, for its button. */
export const FIX_LABEL = {
  snap_box: "Snap to suggested box",
  exclude_view: "Exclude view",
  mirror_labels: "Apply mirrored labels",
  snap_point: "Snap to the trajectory",
};
/** The key of each fix on the system page. */
export const FIX_KEY = { snap_box: "s", exclude_view: "x", mirror_labels: "m", snap_point: "s" };

/** A fix's uncertainty in words: "± 1.5 px" (the box or point the other views agree on, one sigma), or "". */
function sigmaText(suggestion) {
  const s = suggestion.box_sigma_px ?? suggestion.point_sigma_px;
  return isNum(s) ? `± ${s.toFixed(1)} px` : "";
}

/** What placing or confirming a label on a view without an image adds: nobody can look at the ball there. */
export const NO_IMAGE_CHECK = "no image here: the other views alone vouch for it";

/** A fix's button text: a detector's box says whose (and, on a view without an image, that nobody can look at it),
 * a box or point the other views agree on says so, with its uncertainty. */
function fixLabel(suggestion, doubt, v = {}) {
  const sigma = sigmaText(suggestion);
  const ev = (doubt && DETECTOR_KINDS.includes(doubt.kind) && doubt.evidence) || null;
  if (ev) return `Place ${ev.detector}'s box (score ${isNum(ev.score) ? ev.score.toFixed(2) : "?"}${v.image_url ? "" : `; ${NO_IMAGE_CHECK}`})`;
  if (suggestion.action === "snap_box" && sigma) return `Snap to the box the other views agree on (${sigma})`;
  if (suggestion.action === "snap_point" && sigma) return `Snap to the trajectory (${sigma})`;
  return FIX_LABEL[suggestion.action];
}

function fixTitle(suggestion) {
  const sigma = sigmaText(suggestion);
  return `${FIX_LABEL[suggestion.action]}${sigma ? ` (its uncertainty, one standard deviation: ${sigma})` : ""}; it stays a suggestion until you confirm it (Enter)`;
}

/** The buttons of a doubt's other fixes (`suggestion.alternatives`, e.g. exclude the view). */
function alternativeFixes(doubt, excluded, apply) {
  return (doubt.suggestion?.alternatives || [])
    .filter((a) => FIX_LABEL[a] && !(a === "exclude_view" && excluded))
    .map((a) => el("button", { type: "button", "data-testid": "apply-alt-fix", "data-action": a,
      title: `${FIX_LABEL[a]} instead (${FIX_KEY[a]} on the selected view)`, onclick: () => apply(a) },
    `${FIX_LABEL[a]} `, el("kbd", {}, FIX_KEY[a])));
}


function evidenceTitle(evidence) {
  const entries = Object.entries(evidence || {}).filter(([, v]) => isNum(v) || typeof v === "string");
  return entries.length ? entries.map(([k, v]) => `${k}: ${isNum(v) ? Number(v.toFixed(3)) : v}`).join("\n") : null;
}

function residualsTitle(residuals) {
  const entries = Object.entries(residuals || {}).filter(([, px]) => isNum(px)).sort((a, b) => b[1] - a[1]);
  return entries.length ? `line residuals (px):\n${entries.map(([c, px]) => `${c}: ${px.toFixed(2)}`).join("\n")}` : null;
}

export function clamp(x, lo, hi) {
  return Math.min(hi, Math.max(lo, x));
}

/** The doubt items of a view's doubts bar: each doubt's chip, message and fix buttons (`panel.applyFix`,
 * `panel.confirmPlacement`). */
export function viewDoubtItems(v, viewDoubts, excluded, panel) {
  const ball = v.ball || {};
  return viewDoubts.map((d) => {
    const draw = doubtDrawing(d.kind); // the kind's test ids, whose sentence it shows, whether it confirms a placement
    const sentence = draw.sentence_from ? ((v.calibration || {})[draw.sentence_from] || {}).sentence : null;
    const confirms = draw.confirms_placement && ball.kind && ball.provenance;
    return el("div", { class: `doubt${d.accuses_label ? " bad" : ""}`, "data-testid": "view-doubt", "data-kind": d.kind },
    el("span", { class: chipClass("doubt", d.kind), title: word("doubt", d.kind).means }, chip("doubt", d.kind)),
    " ",
    el("span", { class: "msg", "data-testid": draw.message_id, title: evidenceTitle(d.evidence) }, sentence || d.message),
    d.suggestion && FIX_LABEL[d.suggestion.action] && !(d.suggestion.action === "exclude_view" && excluded)
      ? el("button", { type: "button", "data-testid": draw.fix_id, "data-action": d.suggestion.action,
        title: `${fixTitle(d.suggestion)} and recompute (${FIX_KEY[d.suggestion.action]} on the selected view)`,
        onclick: () => panel.applyFix(d) }, `${fixLabel(d.suggestion, d, v)} `, el("kbd", {}, FIX_KEY[d.suggestion.action]))
      : null,
    ...alternativeFixes(d, excluded, (action) => panel.applyFix({ ...d, suggestion: { action } })),
    confirms
      ? el("button", { type: "button", "data-testid": "confirm-placement", title: "Keep this label as yours: it then counts as evidence (Enter)",
        onclick: () => panel.confirmPlacement() }, "Confirm placement ", el("kbd", {}, "Enter"))
      : null,
    confirms && !v.image_url
      ? el("span", { class: "warn", "data-testid": "confirm-no-image" }, ` (${NO_IMAGE_CHECK})`)
      : null);
  });
}

/** The facts list (`<dl class="facts">`) of view `v` in its context {tau, rule, referenceWidth, viewCount, names}. */
export function viewFacts(v, ctx, panel) {
  const { tau, rule, referenceWidth } = ctx;
  const cal = v.calibration || {};
  const jac = cal.jac || {};
  const gammas = Object.keys(jac); // "0.005", ...: the gammas the server stores, in increasing order
  const pct = (g) => String(Number((100 * Number(g)).toFixed(2)));
  const ball = v.ball || {};
  const opt = v.optimised_box;
  const multiView = ctx.viewCount !== 1;
  const excluded = Boolean(v.review?.excluded);
  const err = v.reprojection_error_px;
  const scaled = isNum(v.reprojection_error_scaled_px) ? v.reprojection_error_scaled_px : null;
  const rb = v.reprojected_ball;
  const outside = validPoint(rb) && (rb[0] < 0 || rb[1] < 0 || rb[0] > v.width || rb[1] > v.height);
  const offBy = (px, at) => `${px.toFixed(2)} px` + (isNum(at) && Math.abs(at - px) > 1e-6 ? ` (${at.toFixed(2)} @${referenceWidth})` : "");
  // a placement waiting for Enter makes no 3D ball yet: the error it will show once confirmed, as its doubt says it
  // (one computation on the server, the same number before and after Enter)
  const waiting = ball.provenance
    ? (ctx.doubts || []).find((d) => doubtDrawing(d.kind).confirms_placement && d.evidence
      && "confirmed_error_px" in d.evidence)
    : null;
  const errText = waiting
    ? (isNum(waiting.evidence.confirmed_error_px)
      ? `${offBy(waiting.evidence.confirmed_error_px, waiting.evidence.confirmed_error_scaled_px)} once confirmed`
      : "no 3D ball once confirmed")
    : isNum(err) ? offBy(err, scaled) + (outside ? ", reprojects outside the frame" : "") : "—";

  let boxText = "—";
  if (ball.kind === "box" && validBox(ball.box)) {
    const [x1, y1, x2, y2] = ball.box;
    const [cx, cy] = boxCentre(ball.box);
    boxText = `${(x2 - x1).toFixed(1)} × ${(y2 - y1).toFixed(1)} px at (${cx.toFixed(1)}, ${cy.toFixed(1)})`;
  } else if (ball.kind === "point" && validPoint(ball.point)) {
    boxText = `point (${ball.point[0].toFixed(1)}, ${ball.point[1].toFixed(1)})`;
  } else {
    boxText = "no ball label: drag on the frame to draw a box";
  }
  const optText = opt && validBox(opt.box)
    ? `d ${fmt(opt.d_px, 1)} px, ${fmt(opt.error_m, 2)} m off`
    : "—";

  const flags = (cal.flags || []).map((f) => el("span", { class: chipClass("flag", f), "data-testid": "view-flag", "data-flag": f, title: word("flag", f).means }, chip("flag", f)));
  return el(
    "dl",
    { class: "facts" },
    el("dt", {}, "Calibration"),
    el(
      "dd",
      { "data-testid": "view-calibration", title: residualsTitle(cal.residuals_px) },
      el("span", { class: cal.camera ? (cal.admitted === false ? "bad" : "ok") : "bad" },
        `${cal.status || "none"}${cal.source ? ` · ${cal.source}` : ""}${cal.camera ? (cal.admitted === false ? " · not admitted" : " · admitted") : ""}`),
      flags.length ? " " : null,
      flags,
      cal.reason ? el("div", { class: "reason", "data-testid": "view-reason" }, cal.reason) : null,
      cal.players && cal.players.note ? el("div", { class: "players-note", "data-testid": "view-players-note",
        title: "the players' foot points it was fitted to are the yellow diamonds (a triangle: the head of a player whose feet the image cuts)" }, cal.players.note) : null,
    ),
    el("dt", { "data-testid": "term-jac", title: `${gammas.length ? `JaC@${gammas.map(pct).join("/")} %` : "JaC (not calibrated)"}; ${word("term", "jac").means}` },
      word("term", "jac").chip),
    el(
      "dd",
      { class: "mono", "data-testid": "view-jac" },
      // the gammas the server stores, in its order; the first (the admission's) coloured by the
      // server's admission decision (its threshold is a setting)
      gammas.length ? null : "—",
      // each figure named by its tolerance: three bare percentages read as one figure said three times
      ...gammas.flatMap((g, i) => [
        i ? " · " : null,
        el("span", { "data-testid": "view-jac-gamma", "data-gamma": String(g), class: i ? "" : cal.admitted === true ? "ok" : cal.admitted === false ? "bad" : "",
          title: `the share of the pitch model within ${pct(g)} % of the image diagonal of the labelled lines` },
        `${fmtJac(jac[g])} within ${pct(g)} %`),
      ]),
    ),
    cal.uncertainty ? el("dt", { "data-testid": "term-camera-sigma", title: word("term", "camera_sigma").means }, word("term", "camera_sigma").chip) : null,
    cal.uncertainty ? el("dd", { class: "mono", "data-testid": "view-uncertainty" }, uncertaintyText(cal.uncertainty)) : null,
    el("dt", { "data-testid": "term-reprojection-error", title: `${word("term", "reprojection_error").means}; ${tauText(tau)}, ${word("term", "tau").means} (${rule ? word("rule", rule).means : "rule unknown"})` },
      word("term", "reprojection_error").chip),
    el("dd", { class: `mono ${errorClass(v.reprojection_error_scaled_px, tau)}`, "data-testid": "view-reproj-error" }, errText),
    el("dt", { title: "The annotated ball box: size and centre, image pixels" }, "Ball (red)"),
    el("dd", { class: "mono", "data-testid": "view-box" }, boxText),
    el("dt", { title: "Box consistent with the 3D ball (paper Eq. min_diametre): d_opt, and the distance from the 3D ball to the annotated ray (optimized_error)" }, "Optimised (blue)"),
    el("dd", { class: "mono", "data-testid": "view-opt-box" }, optText),
    el("dt", {}, ""),
    el("dd", { class: "actions" },
      ball.kind ? el("button", { type: "button", "data-testid": "remove-ball", title: "The ball is not visible in this view: remove its label (Delete on the selected view)",
        onclick: () => panel.removeLabel() }, "no ball here") : null,
      ball.edited && (validBox(ball.original_box) || validPoint(ball.original_point))
        ? el("button", { type: "button", "data-testid": "restore-ball", title: "Put back the imported label (z on the selected view)",
          onclick: () => panel.restoreLabel() }, "restore imported")
        : null,
      multiView ? el("button", { type: "button", "data-testid": excluded ? "restore-view" : "exclude-view",
        title: excluded ? "Let this view take part in the 3D ball again (x on the selected view)"
          : "Leave this view out of the triangulation; its labels are kept (x on the selected view)",
        onclick: () => panel.toggleExclusion() }, excluded ? "restore to 3D ball" : "exclude from 3D ball") : null,
      panel.lines.toggleButton()),
    ...panel.lines.facts(),
    ...suggestedNote(ball, ctx.names || {}, () => panel.confirmPlacement()),
    notes(v, multiView).length ? el("dt", {}, "Notes") : null,
    notes(v, multiView).length ? el("dd", { class: "bad", "data-testid": "view-notes" }, notes(v, multiView).join("; ")) : null,
  );
}
