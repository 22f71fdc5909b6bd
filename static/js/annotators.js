// The statistics page's per-person table and plots (GET /api/stats/annotators; reviewers and admins, the panel
// stays hidden for annotators): as an annotator, edits, systems touched and decided, needs fix received, accepted at
// first review, the median time from edit to review, and the geometry's word on each person's ball labels (median
// distance from the ball the other views agree on, px of a 1920-wide image; share accused by a doubt); beside them,
// as a reviewer, the system decisions made (accepted, rejected, needs fix) and the re-reviews of systems that came
// back fixed, as the server counted them. "Download CSV" is the same figures as text/csv. Names come from the server
// and are set as text only.

import { getMe, latestWins, send, toQuery } from "./api.js";
import { el, svg, showError } from "./format.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);

/** [key, heading, how it shows, the group of columns it belongs to]. */
const COLUMNS = [
  ["name", "person", (v) => v],
  ["edits", "edits", String],
  ["systems_touched", "systems touched", String],
  ["systems_decided", "decided", String],
  ["needs_fix_received", "needs fix received", String],
  ["accepted_first_review", "accepted at first review", String],
  ["median_edit_to_review_s", "edit to review (median)", (v) => (v == null ? "—" : v < 120 ? `${v.toFixed(0)} s` : v < 7200 ? `${(v / 60).toFixed(0)} min` : `${(v / 3600).toFixed(1)} h`)],
  ["median_label_distance_px", "label distance (median, px @1920)", (v) => (v == null ? "—" : v.toFixed(1))],
  ["accused_share", "accused by a doubt", (v) => (v == null ? "—" : `${(100 * v).toFixed(0)} %`)],
  ["decisions", "decisions made", String, "review"],
  ["accepted", "accepted", String, "review"],
  ["rejected", "rejected", String, "review"],
  ["needs_fix", "needs fix", String, "review"],
  ["re_reviews", "re-reviews (came back fixed)", String, "review"],
];
const LABELLING = COLUMNS.filter((c) => c[3] !== "review").length - 1;
const REVIEWING = COLUMNS.filter((c) => c[3] === "review").length;

/** Horizontal bars of one figure per person (`key`), the largest full width. */
function barsSvg(items, key, unit, digits = 1) {
  const rows = items.filter((f) => f[key] != null);
  const width = 420;
  const left = 110;
  const h = 16;
  const height = Math.max(1, rows.length) * (h + 4) + 8;
  const top = Math.max(1e-9, ...rows.map((f) => f[key]));
  const root = svg("svg", { viewBox: `0 0 ${width} ${height}`, role: "img", "aria-label": `${key} per annotator` });
  if (!rows.length) root.append(svg("text", { x: 8, y: 14, class: "nodata", text: "no figure yet" }));
  rows.forEach((f, i) => {
    const y = 4 + i * (h + 4);
    const w = ((width - left - 90) * f[key]) / top;
    root.append(svg("text", { x: left - 6, y: y + 12, "text-anchor": "end", text: f.name }),
      svg("rect", { class: "hist-bar", x: left, y, width: Math.max(1, w), height: h }, svg("title", { text: `${f.name}: ${f[key].toFixed(digits)} ${unit}` })),
      svg("text", { x: left + w + 4, y: y + 12, text: `${f[key].toFixed(digits)} ${unit}` }));
  });
  return root;
}

function render(items, query) {
  const body = $("annotator-table").querySelector("tbody");
  body.replaceChildren(...items.map((f) => el("tr", { "data-testid": "annotator-row", "data-name": f.name },
    ...COLUMNS.map(([key, , show, group], i) => el("td", { class: `${i ? "num" : ""}${group === "review" && key === "decisions" ? " group-start" : ""}`, "data-key": key }, show(f[key]))))));
  $("annotators-empty").hidden = items.length > 0;
  $("plot-label-distance").replaceChildren(barsSvg(items, "median_label_distance_px", "px"));
  $("plot-edits").replaceChildren(barsSvg(items, "edits", "edits", 0));
  $("plot-decisions").replaceChildren(barsSvg(items.filter((f) => f.decisions), "decisions", "decisions", 0));
  $("annotators-csv").href = `/api/stats/annotators${toQuery({ ...query, format: "csv" })}`;
}

/** The two dates changed in quick succession ask twice: the figures shown are those of the dates the form says. */
const askFigures = latestWins();

async function load() {
  const latest = askFigures();
  const since = $("annotators-since").value;
  const until = $("annotators-until").value;
  const query = {};
  if (since) query.since = `${since}T00:00:00Z`;
  if (until) query.until = `${until}T00:00:00Z`;
  try {
    const { items } = await send("GET", `/api/stats/annotators${toQuery(query)}`);
    if (latest()) render(items, query);
  } catch (err) {
    if (latest()) showError(`per-annotator figures: ${err.message}`);
  }
}

/** Show the panel (reviewers and admins) and fill it. */
export async function mountAnnotators() {
  const panel = $("annotators");
  if (!panel) return;
  try {
    if ((await getMe()).role === "annotator") return;
  } catch {
    return;
  }
  $("annotator-table").querySelector("thead").replaceChildren(
    el("tr", { class: "groups" }, el("th", {}), el("th", { colspan: String(LABELLING), "data-testid": "group-labelling" }, "as an annotator (labelling)"),
      el("th", { colspan: String(REVIEWING), class: "group-start", "data-testid": "group-reviewing" }, "as a reviewer (system decisions)")),
    el("tr", {}, ...COLUMNS.map(([key, label, , group], i) => el("th", { class: `${i ? "num" : ""}${group === "review" && key === "decisions" ? " group-start" : ""}` }, label))));
  for (const id of ["annotators-since", "annotators-until"]) $(id).addEventListener("change", load);
  panel.hidden = false;
  await load();
}
