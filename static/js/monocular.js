// Detectors page: the ball detectors' boxes imported, one row per source (GET /api/predictions: how many, on which
// views, the spread of their confidence, when and by whom imported), which an admin removes after a confirmation in
// words (DELETE /api/predictions/{source}); the benchmark of a detector's file against the curated balls (POST
// /api/evaluations/monocular: figures per split, the share of views within each distance as SVG); and how close the
// ball boxes are to precise hand-drawn boxes (GET /api/evaluations/boxes, the paper's Table 1). Texts from the server
// are set as text only.
import { ApiError, getMe, send, toQuery } from "./api.js";
import "./session.js";
import { el, svg, fmt, fmtCount, fmtWhen, viewColour } from "./format.js";

const form = document.querySelector("[data-testid=upload-form]");
const errorBar = document.querySelector("[data-testid=error]");

function showError(message) {
  errorBar.querySelector(".msg").textContent = message;
  errorBar.classList.add("visible");
}
errorBar.querySelector("button").addEventListener("click", () => errorBar.classList.remove("visible"));
// the export links and the removal of a source only for the role that may (admins; the API refuses the others)
const mePromise = getMe().catch(() => null);
mePromise.then((me) => {
  document.querySelector("[data-testid=monocular-exports]").hidden = !me || me.role !== "admin";
});

// ----- the detectors' boxes imported ------------------------------------------------------------------------------
const score = (v) => (v === null || v === undefined ? "–" : v.toFixed(2));

/** "0.81 (0.62–0.90; 0.05 – 0.99)": the median, the middle half, the lowest and highest. */
function spreadText(s) {
  if (!s || s.median === null) return "–";
  return `${score(s.median)} (${score(s.q1)}–${score(s.q3)}; ${score(s.min)} – ${score(s.max)})`;
}

/** The inline confirmation of a removal, in words, in place of the row's button. */
function confirmRemoval(cell, source, onDone) {
  const yes = el("button", { type: "button", class: "reject", "data-testid": "source-remove-confirm" }, "Remove them");
  const no = el("button", { type: "button", "data-testid": "source-remove-cancel" }, "Keep");
  const words = el("span", { "data-testid": "source-remove-words" },
    `Remove the ${fmtCount(source.predictions)} ball boxes of ${source.source}? The labels placed from them stay; the ` +
    `${fmtCount(source.systems)} systems they lie on are computed again. `);
  const before = [...cell.childNodes];
  no.addEventListener("click", () => cell.replaceChildren(...before));
  yes.addEventListener("click", async () => {
    yes.disabled = no.disabled = true;
    try {
      const done = await send("DELETE", `/api/predictions/${encodeURIComponent(source.source)}`);
      onDone(`${fmtCount(done.removed)} ball boxes of ${done.source} removed`);
    } catch (err) {
      showError(err instanceof ApiError ? err.message : String(err));
      cell.replaceChildren(...before);
    }
  });
  cell.replaceChildren(words, yes, " ", no);
}

async function loadSources(said = "") {
  const [{ items }, me] = await Promise.all([send("GET", "/api/predictions"), mePromise]);
  const admin = me && me.role === "admin";
  const tbody = document.querySelector("[data-testid=sources-table] tbody");
  tbody.replaceChildren(...items.map((s) => {
    const when = s.imported_at ? fmtWhen(s.imported_at) : { text: "unknown", title: "" };
    const action = el("td", { class: "source-action" });
    if (admin) {
      const remove = el("button", { type: "button", "data-testid": "source-remove", title: "Delete this detector's boxes (asks first)" }, "Remove…");
      remove.addEventListener("click", () => confirmRemoval(action, s, (text) => loadSources(text)));
      action.append(remove);
    }
    return el("tr", { "data-testid": "source-row", "data-source": s.source },
      el("td", { text: s.source }), el("td", { class: "num", text: fmtCount(s.predictions) }),
      el("td", { class: "num", text: fmtCount(s.frames) }), el("td", { class: "num", text: fmtCount(s.systems) }),
      el("td", { class: "mono", "data-testid": "source-scores", text: spreadText(s.scores) }),
      el("td", { "data-testid": "source-when", title: when.title, text: when.text }),
      el("td", { "data-testid": "source-by", text: s.imported_by || "unknown" }), action);
  }));
  document.querySelector("[data-testid=sources-table]").hidden = items.length === 0;
  const empty = document.querySelector("[data-testid=sources-empty]");
  empty.hidden = items.length > 0 && !said;
  empty.textContent = said ? `${said}.${items.length ? "" : " No detector's boxes are imported now."}` : "No detector's boxes are imported yet.";
}
loadSources().catch((err) => showError(err instanceof ApiError ? err.message : String(err)));

async function evaluate(formData) {
  const params = {
    all: formData.get("all") ? "true" : "",
    ball_class: formData.get("ball_class"),
    estimator: formData.get("estimator"),
  };
  const body = new FormData();
  body.append("predictions", formData.get("predictions"));
  return send("POST", `/api/evaluations/monocular${toQuery(params)}`, { body });
}

const pct = (v) => (v === null || v === undefined ? "–" : fmt(100 * v, 1, " %"));

function figuresRow(name, rep) {
  const c = rep.counts;
  return el("tr", { dataset: { testid: `row-${name}` } },
    el("td", { text: name }),
    el("td", { class: "num", dataset: { testid: `ap50-${name}` }, text: rep.AP50 === null ? "–" : rep.AP50.toFixed(4) }),
    el("td", { class: "num", dataset: { testid: `mae-m-${name}` }, text: rep.MAE_m === null ? "–" : rep.MAE_m.toFixed(3) }),
    el("td", { class: "num", dataset: { testid: `mae-pct-${name}` }, text: rep.MAE_pct === null ? "–" : rep.MAE_pct.toFixed(2) }),
    el("td", { class: "num", dataset: { testid: `p2m-${name}` }, text: pct(rep.P_2m) }),
    el("td", { class: "num", text: c.localised }),
    el("td", { class: "num", text: c.reference_views }),
    el("td", { class: "num", text: c.detections }));
}

function curveSvg(series) {
  const W = 640, H = 320, L = 48, R = 150, T = 12, B = 36;
  const tmax = Math.max(...series[0][1].curve.thresholds_m);
  const x = (t) => L + ((W - L - R) * t) / tmax;
  const y = (p) => T + (H - T - B) * (1 - p);
  const root = svg("svg", { viewBox: `0 0 ${W} ${H}`, width: W, height: H, role: "img", "aria-label": "precision-threshold curve" });
  for (let p = 0; p <= 1.0001; p += 0.25) {
    root.append(svg("line", { class: "gridline", x1: L, x2: W - R, y1: y(p), y2: y(p) }));
    root.append(svg("text", { x: L - 6, y: y(p) + 4, "text-anchor": "end", text: `${Math.round(100 * p)}` }));
  }
  for (let t = 0; t <= tmax + 1e-9; t += 2) {
    root.append(svg("text", { x: x(t), y: H - B + 14, "text-anchor": "middle", text: `${t}` }));
  }
  root.append(svg("line", { class: "axis", x1: L, x2: W - R, y1: y(0), y2: y(0) }));
  root.append(svg("line", { class: "axis", x1: L, x2: L, y1: y(0), y2: y(1) }));
  root.append(svg("line", { class: "tau", x1: x(2), x2: x(2), y1: y(0), y2: y(1) }));
  root.append(svg("text", { x: (L + W - R) / 2, y: H - 4, "text-anchor": "middle", text: "threshold τ3D (m)" }));
  root.append(svg("text", { x: 12, y: T + 10, text: "%" }));
  const legend = svg("g", { class: "legend" });
  series.forEach(([name, rep], i) => {
    const pts = rep.curve.thresholds_m
      .map((t, k) => [t, rep.curve.precision[k]])
      .filter(([, p]) => p !== null)
      .map(([t, p]) => `${x(t).toFixed(1)},${y(p).toFixed(1)}`);
    const colour = viewColour(i);
    root.append(svg("polyline", { points: pts.join(" "), stroke: colour, "stroke-dasharray": i ? "6 4" : null, dataset: { testid: `curve-${name}` } }));
    legend.append(svg("line", { x1: W - R + 12, x2: W - R + 32, y1: T + 10 + 16 * i, y2: T + 10 + 16 * i, stroke: colour, "stroke-width": 2 }));
    legend.append(svg("text", { x: W - R + 38, y: T + 14 + 16 * i, text: `${name} (n = ${rep.counts.localised})` }));
  });
  root.append(legend);
  return root;
}

/** How each way of placing the ball from one view reads (the server's names: app.services.evaluation.monocular). */
const ESTIMATOR_WORDS = { exact: "from the ball's exact outline", paper: "from the box's size (the paper's formula)" };

function render(report) {
  const series = [["all", report], ...Object.entries(report.splits)];
  const tbody = document.querySelector("[data-testid=figures] tbody");
  tbody.replaceChildren(...series.map(([name, rep]) => figuresRow(name, rep)));
  document.querySelector("[data-testid=report-note]").textContent =
    `3D ball from one view: ${ESTIMATOR_WORDS[report.estimator] || report.estimator}; ${report.counts.ignored_detections} box(es) left aside in images without a curated 3D ball. ` +
    "Method: AP@0.5 as Pascal VOC (all points); the distances over the views whose box overlaps the curated one.";
  document.querySelector("[data-testid=curve]").replaceChildren(curveSvg(series));
  document.querySelector("[data-testid=report]").hidden = false;
  document.querySelector("[data-testid=report-empty]").hidden = true;
}

form.addEventListener("submit", async (event) => {
  event.preventDefault();
  errorBar.classList.remove("visible");
  const button = form.querySelector("[data-testid=evaluate]");
  button.disabled = true;
  try {
    render(await evaluate(new FormData(form)));
  } catch (err) {
    showError(err instanceof ApiError ? err.message : String(err));
  } finally {
    button.disabled = false;
  }
});

// ----- Table 1: the ball boxes against the stored precise boxes ------------------------------------------------------
const BOX_ROWS = [
  ["original", "as imported"],
  ["optimised", "optimised (agreeing with the 3D ball)"],
  ["refined", "refined (the export's ball box)"],
];

function renderBoxes(report) {
  const tbody = document.querySelector("[data-testid=boxes-table] tbody");
  tbody.replaceChildren(...BOX_ROWS.map(([key, label]) => {
    const r = report[key];
    return el("tr", { dataset: { testid: `boxes-${key}` } },
      el("td", { text: label }),
      el("td", { class: "num", text: r.n }),
      el("td", { class: "num", dataset: { testid: `boxes-iou-${key}` }, text: r.iou === null ? "–" : r.iou.toFixed(3) }),
      el("td", { class: "num", dataset: { testid: `boxes-size-${key}` }, text: r.size_error_pct === null ? "–" : r.size_error_pct.toFixed(1) }));
  }));
  document.querySelector("[data-testid=boxes-note]").textContent = report.views
    ? `${report.views} view(s) with a precise box. Overlap (IoU) and how far the size is off (|diagonal − precise diagonal| / precise diagonal) are means over the views that have each box.`
    : "No view of the chosen systems has a precise box: store them with v3d import precise-boxes PRECISE.csv (league,season,match,image,x1,y1,x2,y2).";
}

async function scoreBoxes(all) {
  try {
    renderBoxes(await send("GET", `/api/evaluations/boxes${toQuery({ all: all ? "true" : "" })}`));
  } catch (err) {
    showError(err instanceof ApiError ? err.message : String(err));
  }
}

const boxesForm = document.querySelector("[data-testid=boxes-form]");
boxesForm.addEventListener("submit", (event) => {
  event.preventDefault();
  scoreBoxes(new FormData(boxesForm).get("all"));
});
scoreBoxes(false);
