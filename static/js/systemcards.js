// The system page's summary cards, drawn from the system view's JSON: the doubts bar (one chip per label
// doubt, then one per view whose state needs an eye), the review status badge, the 3D ball with the
// triangulation's rule, and the pairs table (each pair's error, parallax, baseline, kept or dropped and why).

import { el, fmt, fmtXYZ, isNum, STATUS_LABEL } from "./format.js";
import { notes } from "./viewfacts.js";
import { decisionNote } from "./viewdecisions.js";
import { WORDS, chip, chipClass, heightText, tauText } from "./words.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);

/** One chip per label doubt of the server (a click selects and scrolls to its view), then one per
 * view whose state needs an eye (calibration, error above tau): nothing doubtful is left below the
 * fold unnoticed. */
export function renderDoubts(sys, select) {
  const chips = [];
  const indexOf = (fid) => sys.views.findIndex((v) => v.frame_id === fid);
  for (const d of sys.doubts || []) {
    if (!d.accuses_label) continue;
    const i = indexOf(d.frame_id);
    chips.push(el("button", { type: "button", class: chipClass("doubt", d.kind), "data-testid": "doubt", "data-kind": d.kind, title: d.message,
      onclick: () => { if (i >= 0) { select(i); $("views").children[i]?.scrollIntoView({ behavior: "smooth", block: "center" }); } } },
    `${i >= 0 ? `V${i + 1} ` : ""}${chip("doubt", d.kind)}`));
  }
  sys.views.forEach((v, i) => {
    const why = notes(v, sys.views.length !== 1);
    if (!why.length) return;
    chips.push(el("button", { type: "button", class: "chip bad", "data-testid": "doubt", title: why.join("; "),
      onclick: () => $("views").children[i]?.scrollIntoView({ behavior: "smooth", block: "center" }) },
    `V${i + 1} ${shortDoubt(why[0])}${why.length > 1 ? ` +${why.length - 1}` : ""}`));
  });
  if (!Array.isArray(sys.ball3d) && sys.views.length > 1) {
    chips.push(el("span", { class: chipClass("note", "no_ball3d"), "data-testid": "doubt", title: WORDS.note.no_ball3d.means },
      `${WORDS.note.no_ball3d.chip} (${sys.triangulation?.status ? chip("triangulation", sys.triangulation.status) : "not triangulated"})`));
  }
  $("system-doubts").replaceChildren(...chips);
}

/** The system's decision: its badge, the current decision key, when it was decided (or why it is pending again)
 * and, when a batch accepted it after a random sample (`batch`: the system view's accepted_in_batch), which batch
 * and its plan in words, as a release's document says it. */
export function renderStatus(review, batch = null) {
  const status = review?.status || "pending";
  const badge = $("system-status");
  badge.className = `badge ${status}`;
  badge.textContent = STATUS_LABEL[status] || status;
  for (const id of ["accept", "reject", "needs-fix"]) {
    $(id).classList.toggle("current", $(id).dataset.status === status);
  }
  $("review-meta").textContent = decisionNote(review);
  $("review-meta").classList.toggle("bad", status === "pending" && Boolean(review?.reset_reason));
  const byBatch = status === "accepted" && batch && review?.batch_id === batch.batch_id;
  $("review-batch").hidden = !byBatch;
  $("review-batch").textContent = byBatch ? batchNote(batch) : "";
}

/** A batch's acceptance in words: "Accepted in batch 7 after a sample of 59 of 240 (made by rev, accepted by
 * rev): if none of these 59 is wrong, you can be 95 % sure that at most 5 % of the 240 are." */
export function batchNote(batch) {
  const who = batch.decided_by ? `, accepted by ${batch.decided_by}` : "";
  return `Accepted in batch ${batch.batch_id} after a sample of ${batch.sample} of ${batch.systems} ` +
    `(made by ${batch.created_by}${who}), not looked at by a person: ${batch.plan}.`;
}

export function renderBall(sys) {
  const b = sys.ball3d;
  const ok = Array.isArray(b) && b.every(isNum);
  $("ball3d-x").textContent = ok ? `${b[0].toFixed(2)} m` : "—";
  $("ball3d-y").textContent = ok ? `${b[1].toFixed(2)} m` : "—";
  $("ball3d-z").textContent = ok ? `${b[2].toFixed(2)} m` : "—";
  $("ball3d-h").textContent = ok ? heightText(b[2], 2) : "—";
  $("ball3d").title = ok ? `world metres, z down: (${fmtXYZ(b, 3)})` : "no 3D ball";
  // how far the ball may lie off: its sigma along its least certain direction (none for a kind that does not weigh it)
  const sigma = sys.ball_sigma_m;
  $("ball3d-sigma").hidden = !(ok && isNum(sigma));
  $("ball3d-sigma").textContent = ok && isNum(sigma) ? `3D ball ± ${sigma.toFixed(2)} m` : "";
  renderEvidence(sys);
  const tri = sys.triangulation || {};
  $("triangulation-status").textContent = tri.status ? `· ${chip("triangulation", tri.status)}` : "";
  const kept = (tri.pairs || []).filter((p) => p.kept).length;
  $("triangulation-rule").textContent =
    `${tauText(tri.tau_px)} (${tri.rule ? chip("rule", tri.rule) : "?"}), baseline ≥ ${fmt(tri.min_baseline_m, 1)} m; ` +
    `${kept} of ${(tri.pairs || []).length} pairs kept.`;
}

// What backs the 3D ball (app.geometry.ball_evidence): the tier the server stored with it and why, in its words.
const TIERS = {
  vouched: { text: "vouched", cls: "accepted", means: "no label doubt, and evidence beside its two rays agrees" },
  unconfirmed: { text: "unconfirmed", cls: "needs_fix", means: "it rests on its views' own agreement: nothing else checks it" },
  doubted: { text: "doubted", cls: "rejected", means: "a label doubt names a view it uses" },
};

function renderEvidence(sys) {
  const tier = TIERS[sys.ball_evidence];
  $("ball-evidence").hidden = !tier;
  const badge = $("ball-evidence-tier");
  badge.className = `badge ${tier ? tier.cls : ""}`;
  badge.textContent = tier ? tier.text : "";
  badge.title = tier ? tier.means : "";
  $("ball-evidence").dataset.tier = sys.ball_evidence || "none";
  $("ball-evidence-reasons").replaceChildren(...(tier ? sys.ball_evidence_reasons || [] : [])
    .map((r) => el("li", { "data-testid": "ball-evidence-reason" }, String(r))));
}

export function renderPairs(sys) {
  const views = sys.views;
  const labelOf = (ref) => {
    const i = views.findIndex((v) => v.frame_id === ref || v.name === ref || String(v.frame_id) === String(ref));
    return i < 0 ? String(ref) : `V${i + 1}`;
  };
  const tri = sys.triangulation || {};
  const tbody = $("pairs").querySelector("tbody");
  const rows = (tri.pairs || []).map((p) =>
    el(
      "tr",
      { class: p.kept ? "kept" : "dropped", "data-testid": "pair", title: Array.isArray(p.point) ? `p_ij = (${fmtXYZ(p.point, 2)}) m` : null },
      el("td", { class: "mono" }, `${labelOf(p.view_a)}–${labelOf(p.view_b)}`),
      el("td", { class: `num ${isNum(p.error_px) && isNum(tri.tau_px) ? (p.error_px < tri.tau_px ? "ok" : "bad") : ""}` }, fmt(p.error_px, 2)),
      el("td", { class: `num ${isNum(p.parallax_deg) && p.parallax_deg < 5 ? "warn" : ""}` }, fmt(p.parallax_deg, 1, "°")),
      el("td", { class: `num ${isNum(p.baseline_m) && isNum(tri.min_baseline_m) && p.baseline_m < tri.min_baseline_m ? "bad" : ""}` }, fmt(p.baseline_m, 1, " m")),
      el("td", {}, p.kept ? el("span", { class: "ok" }, "kept") : el("span", { class: "bad" }, "dropped"),
        !p.kept && p.reason ? el("div", { class: "reason muted", title: WORDS.pair_reason[p.reason]?.means }, chip("pair_reason", p.reason)) : null),
    ),
  );
  if (!rows.length) {
    rows.push(el("tr", {}, el("td", { colspan: 5, class: "muted" }, "No pair: fewer than two calibrated views with a ball label.")));
  }
  tbody.replaceChildren(...rows);
}


const SHORT_DOUBTS = {
  "reprojection error above τ": WORDS.note.error_above_tau.chip,
  "calibration not admitted": WORDS.note.not_admitted.chip,
  "excluded from the 3D ball": WORDS.note.excluded.chip,
};
/** Short form of a doubt for the top bar (the full list is in the chip's title and the view card). */
function shortDoubt(text) {
  if (SHORT_DOUBTS[text]) return SHORT_DOUBTS[text];
  if (text.startsWith("not calibrated")) return WORDS.note.not_calibrated.chip;
  return text;
}
