// Dataset statistics page (static/stats.html): GET /api/stats drawn by the browser as inline SVG, no plotting
// library: images per kind and split (admitted, calibrated, not calibrated), systems kept against the JaC admission
// threshold (the paper's Fig. 3) and histograms of JaC, pairwise reprojection error, camera-to-ball distance and
// ball box size. Every number shown comes from the server's answer (app/services/evaluation/stats.py).
import { ApiError, send } from "./api.js";
import "./session.js";
import { mountExports } from "./exports.js";
import { mountAnnotators } from "./annotators.js";
import { el, svg, showError, viewColour } from "./format.js";

const W = 560; // SVG user units; the plots scale to their panel
const M = { left: 56, right: 14, top: 26, bottom: 40 };

/** "12,345" */
const int = (n) => Number(n).toLocaleString("en-US");

/** About `count` round tick values covering [lo, hi]. */
function ticks(lo, hi, count = 5) {
  if (!(hi > lo)) return [lo];
  const raw = (hi - lo) / count;
  const mag = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 2.5, 5, 10].map((f) => f * mag).find((s) => s >= raw);
  const out = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9; t += step) out.push(Number(t.toPrecision(12)));
  return out;
}

/** The frame of a plot: axes, horizontal grid lines with their labels, the axis titles. */
function frame(H, yMax, xTitle, yTitle) {
  // a chart is an image to a screen reader: its axes' titles name it
  const root = svg("svg", { viewBox: `0 0 ${W} ${H}`, role: "img", "aria-label": `${yTitle} by ${xTitle}` });
  const y = (v) => M.top + (H - M.top - M.bottom) * (1 - v / (yMax || 1));
  for (const t of ticks(0, yMax || 1, 4)) {
    if (!Number.isInteger(t) && yMax >= 4) continue;
    root.append(svg("line", { class: "gridline", x1: M.left, x2: W - M.right, y1: y(t), y2: y(t) }));
    root.append(svg("text", { x: M.left - 6, y: y(t) + 4, "text-anchor": "end", text: int(t) }));
  }
  root.append(svg("line", { class: "axis", x1: M.left, x2: W - M.right, y1: y(0), y2: y(0) }));
  root.append(svg("line", { class: "axis", x1: M.left, x2: M.left, y1: M.top, y2: y(0) }));
  root.append(svg("text", { x: (M.left + W - M.right) / 2, y: H - 6, "text-anchor": "middle", text: xTitle }));
  root.append(svg("text", { x: 12, y: (M.top + H - M.bottom) / 2, "text-anchor": "middle",
    transform: `rotate(-90 12 ${(M.top + H - M.bottom) / 2})`, text: yTitle }));
  return { root, y };
}

function noData(text) {
  return svg("svg", { viewBox: `0 0 ${W} 60`, role: "img", "aria-label": text },
    svg("text", { class: "nodata", x: W / 2, y: 34, "text-anchor": "middle", text }));
}

/** A histogram {edges, counts, n} as bars; `scale` turns a value into its shown unit (e.g. JaC as %). */
export function histogramSvg(hist, { xTitle, digits = 1, scale = 1 }) {
  if (!hist || !hist.n) return noData("nothing to count yet");
  const H = 230;
  const yMax = Math.max(...hist.counts);
  const lo = hist.edges[0] * scale, hi = hist.edges[hist.edges.length - 1] * scale;
  const { root, y } = frame(H, yMax, xTitle, "count");
  const span = hi - lo || 1;
  const x = (v) => M.left + ((W - M.left - M.right) * (v * scale - lo)) / span;
  hist.counts.forEach((c, i) => {
    const x0 = x(hist.edges[i]), x1 = x(hist.edges[i + 1]);
    const from = (hist.edges[i] * scale).toFixed(digits), to = (hist.edges[i + 1] * scale).toFixed(digits);
    root.append(svg("rect", { class: "hist-bar", x: x0 + 0.5, width: Math.max(x1 - x0 - 1, 0.5), y: y(c), height: y(0) - y(c),
      dataset: { testid: "bar", count: c } }, svg("title", { text: `${from} to ${to}: ${int(c)}` })));
  });
  for (const t of ticks(lo, hi, 6)) {
    const px = M.left + ((W - M.left - M.right) * (t - lo)) / span;
    root.append(svg("line", { class: "axis", x1: px, x2: px, y1: y(0), y2: y(0) + 4 }));
    root.append(svg("text", { x: px, y: y(0) + 16, "text-anchor": "middle", text: `${t}` }));
  }
  const tail = hist.above ? `; ${int(hist.above)} above ${hi.toFixed(digits)} not drawn` : "";
  root.append(svg("text", { class: "title", x: W - M.right, y: 12, "text-anchor": "end", text: `n = ${int(hist.n)}${tail}`,
    dataset: { testid: "histogram-n" } }));
  return root;
}

/** Systems kept against the admission threshold (Fig. 3): one line per kind ([kind, sweep, systems of the kind]),
 * as a percentage of the kind's systems so that kinds of different sizes read alike (the counts in each point's
 * title), the threshold in force marked. */
export function sweepSvg(series, admission) {
  series = series.filter(([, sweep]) => sweep.length && sweep[0].systems_kept > 0);
  if (!series.length) return noData("no multi-view system with two calibrated views yet");
  const H = 260;
  const gammaPct = Number((100 * admission.gamma).toFixed(2));
  const { root, y } = frame(H, 100, `admission threshold: JaC@${gammaPct} % above (%)`, "systems kept (% of the kind's)");
  const x = (t) => M.left + (W - M.left - M.right) * t;
  for (let t = 0; t <= 1.0001; t += 0.2) {
    root.append(svg("text", { x: x(t), y: y(0) + 16, "text-anchor": "middle", text: `${Math.round(100 * t)}` }));
  }
  const at = admission.jac_min;
  root.append(svg("line", { class: "threshold", x1: x(at), x2: x(at), y1: M.top, y2: y(0), dataset: { testid: "threshold" } },
    svg("title", { text: `in force: JaC@${gammaPct} % > ${Math.round(100 * at)} %` })));
  let legendX = M.left;
  series.forEach(([kind, sweep, total], i) => {
    const colour = viewColour(i);
    const pct = (r) => (100 * r.systems_kept) / (total || 1);
    root.append(svg("polyline", { class: "sweep", stroke: colour, points: sweep.map((r) => `${x(r.threshold).toFixed(1)},${y(pct(r)).toFixed(1)}`).join(" ") }));
    for (const r of sweep) {
      root.append(svg("circle", { class: "sweep", fill: colour, cx: x(r.threshold), cy: y(pct(r)), r: 3, dataset: { testid: "sweep-point", kind } },
        svg("title", { text: `${kind}, JaC > ${Math.round(100 * r.threshold)} %: ${int(r.systems_kept)} of ${int(total)} systems` })));
    }
    const label = `${kind} (${int(total)} systems)`;
    root.append(svg("line", { x1: legendX, x2: legendX + 18, y1: 8, y2: 8, stroke: colour, "stroke-width": 2 }));
    root.append(svg("text", { class: "title", x: legendX + 22, y: 12, text: label }));
    legendX += 40 + 7 * label.length;
  });
  return root;
}

/** Images per kind and split as stacked horizontal bars: admitted, calibrated only, not calibrated. */
export function countsSvg(rows) {
  if (!rows.length) return noData("the database holds no system yet");
  const CW = 860, rowH = 24, labelW = 190, H = M.top + rowH * rows.length + 34;
  const max = Math.max(...rows.map((r) => r.images));
  const x = (v) => labelW + ((CW - labelW - 80) * v) / (max || 1);
  const root = svg("svg", { viewBox: `0 0 ${CW} ${H}`, role: "img",
    "aria-label": "images per kind and split: admitted, calibrated only, not calibrated" });
  rows.forEach((r, i) => {
    const top = M.top + i * rowH;
    root.append(svg("text", { x: labelW - 8, y: top + 15, "text-anchor": "end", text: `${r.kind} · ${r.split}` }));
    let at = 0;
    for (const [cls, n, what] of [["admitted", r.admitted_images, "admitted"],
      ["calibrated", r.calibrated_images - r.admitted_images, "calibrated, not admitted"],
      ["uncalibrated", r.images - r.calibrated_images, "not calibrated"]]) {
      if (n > 0) {
        root.append(svg("rect", { class: `seg ${cls}`, x: x(at), y: top + 3, width: x(at + n) - x(at), height: rowH - 8,
          dataset: { testid: `seg-${cls}` } }, svg("title", { text: `${r.kind} ${r.split}: ${int(n)} ${what}` })));
      }
      at += n;
    }
    root.append(svg("text", { x: x(r.images) + 6, y: top + 15, text: `${int(r.images)} images` }));
  });
  const legendY = H - 12;
  [["admitted", "admitted"], ["calibrated", "calibrated, not admitted"], ["uncalibrated", "not calibrated"]].forEach(([cls, text], i) => {
    root.append(svg("rect", { class: cls, x: labelW + 200 * i, y: legendY - 9, width: 10, height: 10 }));
    root.append(svg("text", { x: labelW + 200 * i + 14, y: legendY, text }));
  });
  return root;
}

/** One table row per kind and split (the kind's total first). */
function countRows(kinds) {
  const rows = [];
  for (const [kind, k] of Object.entries(kinds)) {
    rows.push({ kind, split: "all", ...k });
    for (const [split, c] of Object.entries(k.splits).sort()) rows.push({ kind, split, ...c });
  }
  return rows;
}

function countsTable(rows) {
  return rows.map((r) => el("tr", { dataset: { testid: `count-${r.kind}-${r.split}` }, class: r.split === "all" ? "total" : null },
    el("td", { text: r.split === "all" ? r.kind : "" }),
    el("td", { text: r.split }),
    el("td", { class: "num", dataset: { testid: "systems" }, text: int(r.systems) }),
    el("td", { class: "num", dataset: { testid: "images" }, text: int(r.images) }),
    el("td", { class: "num", text: int(r.calibrated_images) }),
    el("td", { class: "num", text: int(r.admitted_images) }),
    el("td", { class: "num", text: r.images ? `${((100 * r.admitted_images) / r.images).toFixed(1)}` : "–" })));
}

// What each tier of ball_evidence means (app.geometry.ball_evidence); the API counts them in this order.
const TIER_MEANING = {
  vouched: "no label doubt, and evidence beside its two rays agrees (a third view, the detector)",
  unconfirmed: "it rests on its views' own agreement: nothing else checks it",
  doubted: "a label doubt names a view it uses",
  none: "no 3D ball",
};

function evidenceTable(counts) {
  return Object.entries(counts).map(([tier, n]) => el("tr", { dataset: { testid: `evidence-${tier}` } },
    el("td", { text: tier }),
    el("td", { class: "num", dataset: { testid: "systems" }, text: int(n) }),
    el("td", { text: TIER_MEANING[tier] || "" })));
}

const HISTOGRAMS = {
  jac: { xTitle: "JaC at the admission gamma (%)", scale: 100, digits: 1 },
  pair_reprojection_error_px: { xTitle: "pairwise reprojection error e_ij (px)", digits: 1 },
  ball_distance_m: { xTitle: "camera centre to 3D ball (m)", digits: 1 },
  box_size_px: { xTitle: "ball box diagonal (px)", digits: 1 },
};

function render(stats) {
  const rows = countRows(stats.kinds);
  document.querySelector("[data-testid=counts] tbody").replaceChildren(...countsTable(rows));
  document.querySelector("[data-testid=evidence] tbody").replaceChildren(...evidenceTable(stats.ball_evidence));
  document.querySelector("[data-testid=plot-counts]").replaceChildren(countsSvg(rows.filter((r) => r.split !== "all")));
  const series = Object.entries(stats.jac_sweep_by_kind).map(([kind, sweep]) => [kind, sweep, stats.kinds[kind].systems]);
  document.querySelector("[data-testid=plot-sweep]").replaceChildren(sweepSvg(series, stats.admission));
  const a = stats.admission;
  const keptAt = (sweep) => sweep.reduce((best, r) => (r.threshold <= a.jac_min ? r : best), sweep[0]);
  const kept = series.filter(([, sweep]) => sweep.length && sweep[0].systems_kept > 0)
    .map(([kind, sweep]) => `${kind} ${int(keptAt(sweep).systems_kept)}`);
  document.querySelector("[data-testid=sweep-note]").textContent =
    `A multi-view system is kept at a threshold when at least two of its views have JaC@${Number((100 * a.gamma).toFixed(2))} % above it. ` +
    `In force: ${Math.round(100 * a.jac_min)} %` + (kept.length ? ` (systems kept at ${Math.round(100 * keptAt(stats.jac_sweep).threshold)} %: ${kept.join(", ")}).` : ".");
  for (const [name, opts] of Object.entries(HISTOGRAMS)) {
    document.querySelector(`[data-testid=plot-${name}]`).replaceChildren(histogramSvg(stats.distributions[name], opts));
  }
  const stale = document.querySelector("[data-testid=stale]");
  stale.textContent = `${int(stats.stale_systems)} system(s) were computed with other settings (a changed V3D_PROFILE): ` +
    "their figures are stale until `v3d recompute`.";
  stale.hidden = !stats.stale_systems;
  document.querySelector("[data-testid=stats]").hidden = false;
  document.querySelector("[data-testid=stats-loading]").hidden = true;
}

document.querySelector("[data-testid=error-dismiss]").addEventListener("click",
  () => document.querySelector("[data-testid=error]").classList.remove("visible"));

send("GET", "/api/stats").then(render).catch((err) => {
  document.querySelector("[data-testid=stats-loading]").textContent = "The statistics could not be loaded.";
  showError(err instanceof ApiError ? err.message : String(err));
});

mountExports(document.querySelector('[data-testid="exports"]')); // admins only: every export as a job
mountAnnotators(); // reviewers and admins: the per-annotator table and plots
