// Releases page (static/releases.html): GET /api/releases as a table, and the diff of two
// (GET /api/releases/{a}/diff/{b}) as a table of the systems added, removed and changed with a histogram of how far
// each changed system's 3D ball moved (inline SVG, no plotting library). Every text comes from the server's answer
// and is set as text, never as markup.
import { send } from "./api.js";
import "./session.js";
import { el, svg, showError } from "./format.js";

const W = 560, H = 220;
const M = { left: 48, right: 12, top: 16, bottom: 40 };

/** Counts of `values` in `bins` equal bins over [0, max]: {edges, counts}. */
export function histogram(values, bins = 10) {
  const hi = Math.max(...values, 0) || 1;
  const edges = Array.from({ length: bins + 1 }, (_, i) => (hi * i) / bins);
  const counts = new Array(bins).fill(0);
  for (const v of values) counts[Math.min(bins - 1, Math.floor((v / hi) * bins))] += 1;
  return { edges, counts };
}

function histogramSvg(values) {
  if (!values.length) {
    return svg("svg", { viewBox: `0 0 ${W} 60`, role: "img" },
      svg("text", { class: "nodata", x: W / 2, y: 34, "text-anchor": "middle", text: "no 3D ball moved" }));
  }
  const { edges, counts } = histogram(values);
  const yMax = Math.max(...counts);
  const root = svg("svg", { viewBox: `0 0 ${W} ${H}`, role: "img", "data-testid": "moves-svg" });
  const y = (c) => M.top + (H - M.top - M.bottom) * (1 - c / yMax);
  const x = (v) => M.left + ((W - M.left - M.right) * v) / edges[edges.length - 1];
  counts.forEach((c, i) => {
    const bar = svg("rect", { class: "hist-bar", x: x(edges[i]) + 1, width: Math.max(1, x(edges[i + 1]) - x(edges[i]) - 2),
      y: y(c), height: y(0) - y(c), "data-count": c });
    bar.append(svg("title", { text: `${edges[i].toFixed(3)}-${edges[i + 1].toFixed(3)} m: ${c}` }));
    root.append(bar);
  });
  root.append(svg("line", { class: "axis", x1: M.left, x2: W - M.right, y1: y(0), y2: y(0) }));
  root.append(svg("text", { x: M.left - 6, y: y(yMax) + 4, "text-anchor": "end", text: String(yMax) }));
  root.append(svg("text", { x: M.left, y: y(0) + 16, "text-anchor": "middle", text: "0" }));
  root.append(svg("text", { x: W - M.right, y: y(0) + 16, "text-anchor": "end",
    text: edges[edges.length - 1].toFixed(3) }));
  root.append(svg("text", { x: (M.left + W - M.right) / 2, y: H - 6, "text-anchor": "middle",
    text: "3D ball moved (m), changed systems" }));
  return root;
}

function viewsText(views) {
  return (views || []).map((v) => `${v.view}: ${v.changes.join(", ")}`).join("; ");
}

async function showDiff(a, b) {
  const url = `/api/releases/${encodeURIComponent(a)}/diff/${encodeURIComponent(b)}`;
  const diff = await send("GET", url);
  const body = document.querySelector("[data-testid=diff-table] tbody");
  body.replaceChildren();
  for (const [change, items] of [["added", diff.added], ["removed", diff.removed], ["changed", diff.changed]]) {
    for (const s of items) {
      const moved = s.ball3d_moved_m === undefined || s.ball3d_moved_m === null ? "" : s.ball3d_moved_m.toFixed(3);
      body.append(el("tr", { dataset: { change, system: String(s.system_id) } },
        el("td", { text: change }), el("td", { class: "num", text: String(s.system_id) }),
        el("td", { text: s.name }), el("td", { text: s.game }), el("td", { class: "num", text: moved }),
        el("td", { text: viewsText(s.views) })));
    }
  }
  document.querySelector("[data-testid=diff-table]").hidden = false;
  document.querySelector("[data-testid=diff-counts]").textContent =
    `${diff.added.length} added, ${diff.removed.length} removed, ${diff.changed.length} changed, ` +
    `${diff.unchanged} unchanged`;
  const moves = diff.changed.map((s) => s.ball3d_moved_m).filter((m) => typeof m === "number");
  document.querySelector("[data-testid=diff-histogram]").replaceChildren(histogramSvg(moves));
  const csv = document.querySelector("[data-testid=diff-csv]");
  csv.href = `${url}?format=csv`;
  csv.hidden = false;
}

async function load() {
  const { items } = await send("GET", "/api/releases");
  const body = document.querySelector("[data-testid=releases] tbody");
  body.replaceChildren(...items.map((r) => el("tr", { dataset: { release: r.name } },
    el("td", { text: r.name }), el("td", { text: r.created_at }), el("td", { text: r.created_by }),
    el("td", { class: "num", text: String(r.systems) }), el("td", { class: "num", text: String(r.views) }),
    el("td", { class: "hash", text: r.hash }), el("td", { text: r.note }))));
  const from = document.querySelector("[data-testid=diff-from]");
  const to = document.querySelector("[data-testid=diff-to]");
  for (const select of [from, to]) {
    select.replaceChildren(...items.map((r) => el("option", { value: r.name, text: r.name })));
  }
  if (items.length >= 2) {
    from.value = items[items.length - 2].name;
    to.value = items[items.length - 1].name;
  }
  document.querySelector("[data-testid=diff-form]").addEventListener("submit", (event) => {
    event.preventDefault();
    showDiff(from.value, to.value).catch((e) => showError(e.message));
  });
}

load().catch((e) => showError(e.message));
