// Monocular 3D ball benchmark page: uploads predictions to POST /api/evaluations/monocular and shows
// the report (figures per split, precision-threshold curve as SVG); and the paper's Table 1 from
// GET /api/evaluations/boxes (original, optimised and refined ball boxes against the stored precise boxes).
import { ApiError, getMe, send, toQuery } from "./api.js";
import "./session.js";
import { el, svg, fmt, viewColour } from "./format.js";

const form = document.querySelector("[data-testid=upload-form]");
const errorBar = document.querySelector("[data-testid=error]");

function showError(message) {
  errorBar.querySelector(".msg").textContent = message;
  errorBar.classList.add("visible");
}
errorBar.querySelector("button").addEventListener("click", () => errorBar.classList.remove("visible"));
// the export links only for the role that may export (admins; the API refuses the others)
getMe().then((me) => {
  document.querySelector("[data-testid=monocular-exports]").hidden = me.role !== "admin";
}).catch(() => {});

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

function render(report) {
  const series = [["all", report], ...Object.entries(report.splits)];
  const tbody = document.querySelector("[data-testid=figures] tbody");
  tbody.replaceChildren(...series.map(([name, rep]) => figuresRow(name, rep)));
  document.querySelector("[data-testid=report-note]").textContent =
    `Monocular ball: ${report.estimator}; ${report.counts.ignored_detections} detection(s) ignored in images without a 3D ball. ` +
    "AP@0.5: Pascal VOC all-point; MAE and P@2 m over views with a detection overlapping the reference box.";
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
  ["original", "original (as imported)"],
  ["optimised", "optimised (consistent with the 3D ball)"],
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
    ? `${report.views} view(s) with a precise box. IoU and size error (|diagonal − precise diagonal| / precise diagonal) are means over the views that have each box.`
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
