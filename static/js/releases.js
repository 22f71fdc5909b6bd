// Releases page (static/releases.html): GET /api/releases as a table (when, in the reader's locale, and by whom),
// for admins a form that makes one (POST /api/releases: the name typed, no confirmation: a release only adds) and
// the Exports panel with the releases as its scope; the diff of two (GET /api/releases/{a}/diff/{b}) as a table of
// the systems added, removed (and why) and changed, each linked to its system page, with how far each changed
// system's 3D ball moved (inline SVG, no plotting library: a histogram, or one dot per system when there are few).
// Every text comes from the server's answer and is set as text, never as markup.
import { getMe, latestWins, send } from "./api.js";
import "./session.js";
import { mountExports } from "./exports.js";
import { el, svg, fmtWhen, showError, clearError } from "./format.js";

const W = 560, H = 220;
const M = { left: 48, right: 12, top: 16, bottom: 40 };
/** Below this many moves a histogram says little: each system is one dot on the distance axis instead. */
const FEW = 5;

/** Counts of `values` in `bins` equal bins over [0, max]: {edges, counts}. */
export function histogram(values, bins = 10) {
  const hi = Math.max(...values, 0) || 1;
  const edges = Array.from({ length: bins + 1 }, (_, i) => (hi * i) / bins);
  const counts = new Array(bins).fill(0);
  for (const v of values) counts[Math.min(bins - 1, Math.floor((v / hi) * bins))] += 1;
  return { edges, counts };
}

/** The end of an axis over [0, v]: the next 1, 2 or 5 times a power of ten at or above `v` (1 for nothing). */
export function niceCeiling(v) {
  if (!(v > 0)) return 1;
  const p = 10 ** Math.floor(Math.log10(v));
  return [1, 2, 5, 10].map((m) => m * p).find((c) => c >= v - 1e-12);
}

/** A few moves: one dot per system on a 0..nice-maximum axis, each labelled with its system (a short plot). */
function dotsSvg(moves) {
  const h = 90;
  const hi = niceCeiling(Math.max(...moves.map((m) => m.moved)));
  const x = (v) => M.left + ((W - M.left - M.right) * v) / hi;
  const axisY = 50;
  const root = svg("svg", { viewBox: `0 0 ${W} ${h}`, role: "img", "aria-label": "how far each changed system's 3D ball moved (m)", class: "dots-plot", "data-testid": "moves-svg", "data-kind": "dots" });
  root.append(svg("line", { class: "axis", x1: M.left, x2: W - M.right, y1: axisY, y2: axisY }));
  moves.forEach((m, i) => {
    const dot = svg("circle", { class: "move-dot", cx: x(m.moved), cy: axisY, r: 5, "data-system": m.system });
    dot.append(svg("title", { text: `${m.name}: ${m.moved.toFixed(3)} m` }));
    root.append(dot, svg("text", { x: x(m.moved), y: axisY - 10 - (i % 2) * 12, "text-anchor": "middle", text: m.name }));
  });
  root.append(svg("text", { x: M.left, y: axisY + 16, "text-anchor": "middle", text: "0" }));
  root.append(svg("text", { x: W - M.right, y: axisY + 16, "text-anchor": "end", text: `${Number(hi.toPrecision(3))} m` }));
  root.append(svg("text", { x: (M.left + W - M.right) / 2, y: h - 4, "text-anchor": "middle",
    text: "how far each changed system's 3D ball moved (m)" }));
  return root;
}

function histogramSvg(moves) {
  if (!moves.length) {
    return svg("svg", { viewBox: `0 0 ${W} 40`, role: "img", "aria-label": "no 3D ball moved", class: "nodata-plot" },
      svg("text", { class: "nodata", x: 8, y: 24, text: "no 3D ball moved" }));
  }
  if (moves.length < FEW) return dotsSvg(moves);
  const { edges, counts } = histogram(moves.map((m) => m.moved));
  const yMax = Math.max(...counts);
  const root = svg("svg", { viewBox: `0 0 ${W} ${H}`, role: "img", "aria-label": "3D ball moved (m), changed systems", "data-testid": "moves-svg", "data-kind": "histogram" });
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

/** What a diff row's change column says: a removed system says why it left. */
const CHANGE_WORDS = { added: "added", changed: "changed" };
function changeText(change, s) {
  return change === "removed" ? `removed: ${s.why || "no longer accepted"}` : CHANGE_WORDS[change];
}

/** Two diffs asked in quick succession: the table shows the one the selects now say. */
const askDiff = latestWins();

async function showDiff(a, b) {
  const latest = askDiff();
  const url = `/api/releases/${encodeURIComponent(a)}/diff/${encodeURIComponent(b)}`;
  let diff;
  try {
    diff = await send("GET", url);
  } catch (e) {
    if (latest()) throw e;
    return;
  }
  if (!latest()) return;
  const body = document.querySelector("[data-testid=diff-table] tbody");
  body.replaceChildren();
  for (const [change, items] of [["added", diff.added], ["removed", diff.removed], ["changed", diff.changed]]) {
    for (const s of items) {
      const moved = s.ball3d_moved_m === undefined || s.ball3d_moved_m === null ? "" : s.ball3d_moved_m.toFixed(3);
      // a deleted system has no page any more: its name stays text
      const link = s.why === "deleted" ? s.name
        : el("a", { href: `/systems/${encodeURIComponent(s.system_id)}`, "data-testid": "diff-system-link" }, s.name);
      body.append(el("tr", { dataset: { change, system: String(s.system_id), why: s.why || "" } },
        el("td", { class: change === "removed" ? "bad" : "", text: changeText(change, s) }),
        el("td", { class: "num", text: String(s.system_id) }),
        el("td", {}, link), el("td", { text: s.game }), el("td", { class: "num", text: moved }),
        el("td", { text: viewsText(s.views) })));
    }
  }
  document.querySelector("[data-testid=diff-table]").hidden = false;
  document.querySelector("[data-testid=diff-counts]").textContent =
    `${diff.added.length} added, ${diff.removed.length} removed, ${diff.changed.length} changed, ` +
    `${diff.unchanged} unchanged`;
  const moves = diff.changed.filter((s) => typeof s.ball3d_moved_m === "number")
    .map((s) => ({ system: s.system_id, name: s.name, moved: s.ball3d_moved_m }));
  document.querySelector("[data-testid=diff-histogram]").replaceChildren(histogramSvg(moves));
  const csv = document.querySelector("[data-testid=diff-csv]");
  csv.href = `${url}?format=csv`;
  csv.hidden = false;
}

/** A release's systems in words: "12 accepted systems (2 without a 3D ball)": an accepted system whose views agreed on
 * no ball is in the release too, and is counted aloud. */
function systemsWords(r) {
  const without = r.without_ball3d ? ` (${r.without_ball3d} without a 3D ball)` : "";
  return `${r.systems} accepted system${r.systems === 1 ? "" : "s"}${without}`;
}

function releaseRow(r) {
  const when = fmtWhen(r.created_at);
  return el("tr", { dataset: { release: r.name } },
    el("td", { text: r.name }),
    el("td", { title: when.title, "data-testid": "release-when", "data-at": r.created_at, text: when.text }),
    el("td", { "data-testid": "release-by", text: r.made_by }),
    el("td", { class: "num", "data-testid": "release-systems",
      title: r.without_ball3d ? `${r.without_ball3d} of them accepted without a 3D ball` : "each with its 3D ball",
      text: r.without_ball3d ? `${r.systems} (${r.without_ball3d} without 3D ball)` : String(r.systems) }),
    el("td", { class: "num", text: String(r.views) }),
    el("td", { class: "hash", text: r.hash }), el("td", { text: r.note }));
}

/** Fill the table and the diff's two selects (the last two releases chosen); answers the releases. */
async function loadReleases() {
  const { items } = await send("GET", "/api/releases");
  document.querySelector("[data-testid=releases] tbody").replaceChildren(...items.map(releaseRow));
  document.querySelector("[data-testid=releases-empty]").hidden = items.length > 0;
  const from = document.querySelector("[data-testid=diff-from]");
  const to = document.querySelector("[data-testid=diff-to]");
  for (const select of [from, to]) {
    select.replaceChildren(...items.map((r) => el("option", { value: r.name, text: r.name })));
  }
  if (items.length >= 2) {
    from.value = items[items.length - 2].name;
    to.value = items[items.length - 1].name;
  }
  return items;
}

/** The admin's form: the name typed, "Create release", and the release exists (a release only adds: no dialog). */
function mountCreate(exportsPanel) {
  const form = document.querySelector("[data-testid=release-form]");
  const text = document.querySelector("[data-testid=release-create-text]");
  const button = document.querySelector("[data-testid=release-create]");
  form.hidden = false;
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const name = form.elements.name.value.trim();
    if (!name) {
      text.textContent = "type the release's name first";
      return;
    }
    button.disabled = true;
    text.textContent = `making ${name}…`;
    try {
      const r = await send("POST", "/api/releases", {
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ name, note: form.elements.note.value }),
      });
      clearError();
      text.textContent = `release ${r.name} made: ${systemsWords(r)}, ${r.views} view${r.views === 1 ? "" : "s"}`;
      form.reset();
      await loadReleases();
      if (exportsPanel) await exportsPanel.addReleases();
    } catch (e) {
      text.textContent = "";
      showError(`release ${name}: ${e.message}`);
    } finally {
      button.disabled = false;
    }
  });
}

async function load() {
  await loadReleases();
  document.querySelector("[data-testid=diff-form]").addEventListener("submit", (event) => {
    event.preventDefault();
    const from = document.querySelector("[data-testid=diff-from]").value;
    const to = document.querySelector("[data-testid=diff-to]").value;
    showDiff(from, to).catch((e) => showError(e.message));
  });
  let me = null;
  try {
    me = await getMe();
  } catch {
    return;
  }
  if (me.role === "admin") {
    const panel = await mountExports(document.querySelector("[data-testid=exports]"), { releasesOnly: true });
    mountCreate(panel);
  }
}

load().catch((e) => showError(e.message));
