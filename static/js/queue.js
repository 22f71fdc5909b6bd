// Queue page: the table of systems, filtered and sorted by the API, with review progress.
// The filters live in the page's query string (a reload or a shared link keeps them) and are handed
// on to the system page, whose "queue" link and prev / next follow the same queue.

import { latestWins, listSystems, listGames } from "./api.js";
import "./session.js";
import { JobsPanel } from "./jobs.js";
import { mountExports } from "./exports.js";
import { mountImport, mountWorkCounts } from "./team.js";

/** A SoccerNet match name ("2015-02-21 - 18-00 Chelsea 1 - 1 Burnley") with its teams and score first and its date
 * after: a narrow column cuts the end, and the date and kick-off alone tell two games of one day apart from nothing.
 * Any other name is shown as it is. */
export function gameShown(match) {
  const m = typeof match === "string" ? /^(\d{4}-\d{2}-\d{2}) - (\d{2})-(\d{2}) (.+)$/.exec(match) : null;
  return m ? `${m[4]} · ${m[1]} ${m[2]}:${m[3]}` : match;
}
import { QueueAssignment } from "./assignment.js";
import { dispatchKey, keysHelp } from "./keys.js";
import { FILTERS, DEFAULT_SORT, readState, stateQuery, apiFilters } from "./queuestate.js";
import { el, fmt, fmtJac, isNum, isTyping, showError, clearError, STATUSES, STATUS_LABEL, DOUBT_LABEL, toast } from "./format.js";
import { WORDS, chip, chipClass, chipLegend, heightText } from "./words.js";
import { resumeLink } from "./pass.js";
import { mountBatchButton } from "./batch.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);
const PAGE_SIZE = 50;

const pageSize = (state) => state.limit || PAGE_SIZE;

/** Query parameters of GET /api/systems for one page of the queue: by cursor when the pager turned
 * pages (keyset paging: as quick at any depth), by offset for a link to page N. */
export function apiParams(state) {
  const page = { limit: pageSize(state) };
  if (state.after) page.after = state.after;
  else if (state.before) page.before = state.before;
  else page.offset = state.page * page.limit;
  return { ...apiFilters(state), ...page };
}

/** Chips for what makes a system doubtful before opening it: the stored doubts per kind first. */
function rowDoubts(s) {
  const chips = [];
  for (const [kind, label] of Object.entries(DOUBT_LABEL)) {
    const n = (s.doubt_counts || {})[kind] || 0;
    if (n > 0) chips.push(el("span", { class: chipClass("doubt", kind), "data-testid": "row-doubt", "data-kind": kind, title: `${n} doubt(s): ${WORDS.doubt[kind].means}` }, `${n} ${label}`));
  }
  const notAdmitted = (s.views_calibrated ?? 0) - (s.views_admitted ?? 0);
  const uncalibrated = (s.views_total ?? 0) - (s.views_calibrated ?? 0);
  const unlabelled = (s.views_total ?? 0) - (s.views_labelled ?? 0);
  // the same words and colours as the system page and the legend (words.js)
  if (s.views_above_tau > 0) chips.push(el("span", { class: chipClass("note", "error_above_tau"), "data-testid": "row-above-tau", title: "admitted labelled views whose reprojection error is above tau (the system page's \"error > τ\")" }, `${s.views_above_tau} ${chip("note", "error_above_tau")}`));
  if (uncalibrated > 0) chips.push(el("span", { class: chipClass("note", "not_calibrated"), title: WORDS.note.not_calibrated.means }, `${uncalibrated} ${chip("note", "not_calibrated")}`));
  if (notAdmitted > 0) chips.push(el("span", { class: chipClass("note", "not_admitted"), title: WORDS.note.not_admitted.means }, `${notAdmitted} ${chip("note", "not_admitted")}`));
  if (s.views_total > 1) { // a single view (calibration data) has no 3D ball to make
    if (unlabelled > 0) chips.push(el("span", { class: chipClass("note", "without_ball") }, `${unlabelled} ${chip("note", "without_ball")}`));
    if (!Array.isArray(s.ball3d)) chips.push(el("span", { class: chipClass("note", "no_ball3d") }, chip("note", "no_ball3d")));
  }
  return chips;
}

class QueuePage {
  state = readState();
  rows = [];
  selected = 0;
  total = 0;
  nextCursor = null;
  prevCursor = null;

  constructor() {
    this.askLoad = latestWins(); // an answer is shown only while its load is still the latest (load)
    const form = $("filters");
    // the doubt filter's kinds and words come from the contract through words.js, before the form is filled
    $("filter-doubt").append(...Object.entries(DOUBT_LABEL).map(([kind, label]) => el("option", { value: kind }, label)));
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this.applyForm();
      // the filter is applied: the next Enter opens the highlighted row, as j / k and Enter do, not Apply again
      if (form.contains(document.activeElement)) document.activeElement.blur();
    });
    form.addEventListener("change", (e) => {
      if (e.target.tagName === "SELECT") this.applyForm();
    });
    $("reset").addEventListener("click", () => {
      this.state = { ...Object.fromEntries(FILTERS.map((k) => [k, ""])), sort: DEFAULT_SORT };
      this.firstPage();
      this.fillForm();
      this.navigate();
    });
    for (const th of document.querySelectorAll("th.sortable")) {
      th.addEventListener("click", () => this.toggleSort(th.dataset.sort));
    }
    $("page-prev").addEventListener("click", () => this.turnPage(-1));
    $("page-next").addEventListener("click", () => this.turnPage(1));
    $("error-dismiss").addEventListener("click", clearError);
    $("queue").querySelector("tbody").addEventListener("click", (e) => {
      if (e.target.closest("a")) return; // the link does it (and honours ctrl-click)
      const tr = e.target.closest("tr[data-id]");
      if (tr) this.open(tr.dataset.id);
    });
    // "My systems", who has what (re-read every 30 s), the assign bar
    this.assignment = new QueueAssignment(this, () => apiParams(this.state));
    this.keys = this.keyTable();
    this.keys.push(keysHelp(this.keys, "Keys of the queue", chipLegend("What the chips say")));
    $("chip-legend-slot")?.replaceChildren(chipLegend("")); // under its <summary>
    document.addEventListener("keydown", (e) => this.onKey(e));
    window.addEventListener("popstate", () => {
      this.state = readState();
      this.fillForm();
      this.load();
    });
    this.fillForm();
    this.loadGames();
    this.load();
    // the person's unfinished review pass (pass.js), resumed where they left it, in any browser
    const resume = el("span", { class: "resume-pass", "data-testid": "resume", hidden: true });
    $("progress-text").after(resume);
    resumeLink(resume);
    mountBatchButton($("batch")); // reviewers: accept the vouched after a random sample (batch.js)
    // an import or a recompute that ends while the page is open changes the queue: reload it
    mountExports($("exports")); // admins only: every export as a job with its download
    mountWorkCounts($("work-counts")); // To fix (and To re-review): what the team's loop sent to this person
    this.jobs = new JobsPanel($("jobs"), (job) => {
      if (job.state === "done" && job.kind !== "export") {
        this.loadGames();
        this.load();
      }
    });
    // admins only: a zip uploaded with its progress, then followed under Jobs, where its row is shown at once
    mountImport($("import"), (job) => this.jobs.show(job));
  }

  fillForm() {
    const form = $("filters");
    for (const key of FILTERS) {
      const input = form.elements[key];
      if (input) input.value = this.state[key];
    }
    this.markSort();
  }

  applyForm() {
    const form = $("filters");
    for (const key of FILTERS) this.state[key] = form.elements[key].value.trim();
    for (const [lo, hi] of [["jac_min", "jac_max"], ["error_min", "error_max"], ["sigma_min", "sigma_max"]]) {
      if (this.state[lo] !== "" && this.state[hi] !== "" && Number(this.state[lo]) > Number(this.state[hi])) {
        showError(`${lo.replace("_", " ")} is larger than ${hi.replace("_", " ")}: nothing can match.`);
        return;
      }
    }
    this.firstPage();
    this.navigate();
  }

  toggleSort(key) {
    const current = this.state.sort;
    // first click: the most doubtful first (most severe, largest error, lowest JaC) or A-Z for names
    const first = key === "worst_error" || key === "doubts" || key === "severity" ? `-${key}` : key;
    const flipped = first.startsWith("-") ? key : `-${key}`;
    this.state.sort = current === first ? flipped : first;
    this.firstPage();
    this.fillForm();
    this.navigate();
  }

  markSort() {
    const s = this.state.sort;
    const key = s.replace(/^-/, "");
    for (const th of document.querySelectorAll("th.sortable")) {
      const arrow = th.querySelector(".arrow");
      const active = th.dataset.sort === key;
      arrow.textContent = active ? (s.startsWith("-") ? "▼" : "▲") : "";
      th.setAttribute("aria-sort", active ? (s.startsWith("-") ? "descending" : "ascending") : "none");
    }
  }

  firstPage() {
    Object.assign(this.state, { page: 0, after: "", before: "" });
  }

  turnPage(delta) {
    const cursor = delta > 0 ? this.nextCursor : this.prevCursor;
    if (!cursor) return;
    const page = Math.max(0, this.state.page + delta);
    if (page === 0) this.firstPage();
    else Object.assign(this.state, { page, after: delta > 0 ? cursor : "", before: delta > 0 ? "" : cursor });
    this.navigate();
  }

  navigate() {
    history.pushState(null, "", `/${stateQuery(this.state)}`); // (drops any #system-… selection)
    this.load();
  }

  async loadGames() {
    try {
      const games = await listGames();
      const select = $("filter-game");
      const items = Array.isArray(games) ? games : games.items || [];
      for (const g of items) {
        select.append(el("option", { value: g.id }, [g.league, g.season, g.match].filter(Boolean).join(" · ") || `game ${g.id}`));
      }
      select.value = this.state.game;
    } catch (err) {
      showError(`games: ${err.message}`);
    }
  }

  async load() {
    this.markSort();
    // the latest load wins: two filters changed in quick succession send two requests whose answers may come back
    // in either order, and the rows shown must be those of the filters the form and the address now say
    const latest = this.askLoad();
    try {
      const answer = await listSystems(apiParams(this.state));
      if (!latest()) return;
      clearError();
      this.rows = answer.items || [];
      this.total = isNum(answer.total) ? answer.total : this.rows.length;
      this.nextCursor = answer.next_cursor || null;
      this.prevCursor = answer.prev_cursor || null;
      if (!this.prevCursor && this.state.page > 0 && (this.state.after || this.state.before)) this.state.page = 0;
      // back from a system page (…#system-12): keep that system selected
      const back = location.hash.match(/^#system-(.+)$/);
      const at = back ? this.rows.findIndex((r) => String(r.id) === decodeURIComponent(back[1])) : -1;
      this.selected = at >= 0 ? at : Math.min(this.selected, Math.max(0, this.rows.length - 1));
      this.renderRows();
      this.assignment.update();
      if (at >= 0) $("queue").querySelectorAll("tbody tr")[at].scrollIntoView({ block: "nearest" });
      this.renderProgress(answer.counts || {});
    } catch (err) {
      if (latest()) showError(err.message);
    }
  }

  renderRows() {
    const handOn = stateQuery(this.state, { withPage: false });
    const tbody = $("queue").querySelector("tbody");
    tbody.replaceChildren(
      ...this.rows.map((s, i) => {
        const game = s.game || {};
        const status = s.review?.status || s.status || "pending";
        const jac = s.lowest_jac;
        return el(
          "tr",
          { "data-testid": "queue-row", "data-id": s.id, tabindex: "-1", class: i === this.selected ? "selected" : "" },
          el("td", { class: "game", "data-testid": "queue-game", title: [game.league, game.season, game.match].filter(Boolean).join(" / ") }, gameShown(game.match) || game.id || "—"),
          el("td", {}, el("a", { href: `/systems/${encodeURIComponent(s.id)}${handOn}`, "data-testid": "system-link" }, s.name),
            this.assignment.chips(s)),
          el("td", {}, el("span", { class: `badge ${status}` }, STATUS_LABEL[status] || status)),
          el("td", { class: `num ${s.views_calibrated < Math.min(2, s.views_total) ? "bad" : ""}`,
            title: `${s.views_calibrated} calibrated, ${s.views_admitted} admitted (JaC@0.5% above the threshold), ${s.views_labelled} with a ball label, of ${s.views_total} views` },
            `${s.views_calibrated ?? "—"}/${s.views_total ?? "—"}`),
          el("td", { class: "num" }, fmt(s.worst_error_px, 2, " px")),
          el("td", { class: "num" }, fmtJac(jac)),
          el("td", { class: "num", title: Array.isArray(s.ball3d) ? "x, y on the pitch (m); height above the grass" : null },
            Array.isArray(s.ball3d) && s.ball3d.every(isNum)
              ? `${s.ball3d[0].toFixed(1)}, ${s.ball3d[1].toFixed(1)} · ${heightText(s.ball3d[2])}`
              : el("span", { class: "muted" }, s.views_total > 1 ? "none" : "single view"),
            s.ball_evidence && s.ball_evidence !== "none"
              ? el("div", { class: `evidence ${s.ball_evidence}`, "data-testid": "row-evidence", title: (s.ball_evidence_reasons || []).join("; ") }, s.ball_evidence)
              : null),
          el("td", { "data-testid": "row-doubts" }, rowDoubts(s)),
        );
      }),
    );
    $("empty").hidden = this.rows.length > 0;
    const size = pageSize(this.state);
    const from = this.rows.length ? this.state.page * size + 1 : 0;
    const to = this.state.page * size + this.rows.length;
    $("page-info").textContent = `${from}–${to} of ${this.total}`;
    $("page-prev").disabled = !this.prevCursor;
    $("page-next").disabled = !this.nextCursor;
  }

  renderProgress(counts) {
    const n = Object.fromEntries(STATUSES.map((s) => [s, isNum(counts[s]) ? counts[s] : 0]));
    const all = STATUSES.reduce((a, s) => a + n[s], 0);
    for (const s of STATUSES) $(`count-${s}`).textContent = String(n[s]);
    const bar = $("progress-bar");
    for (const s of ["accepted", "rejected", "needs_fix", "fixed"]) {
      bar.querySelector(`.${s}`).style.width = all ? `${(100 * n[s]) / all}%` : "0";
    }
    const done = all - n.pending;
    const pct = all ? (100 * done) / all : 0;
    bar.setAttribute("aria-valuenow", pct.toFixed(0));
    $("progress-text").textContent = `${done}/${all} reviewed (${pct.toFixed(0)}%)`;
  }

  select(i) {
    if (!this.rows.length) return;
    this.selected = Math.max(0, Math.min(this.rows.length - 1, i));
    this.assignment.update();
    const trs = $("queue").querySelectorAll("tbody tr");
    trs.forEach((tr, j) => tr.classList.toggle("selected", j === this.selected));
    trs[this.selected].scrollIntoView({ block: "nearest" });
    trs[this.selected].focus({ preventScroll: true });
  }

  open(id) {
    location.assign(`/systems/${encodeURIComponent(id)}${stateQuery(this.state, { withPage: false })}`);
  }

  onKey(e) {
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    if (isTyping(e)) {
      if (e.key === "Escape") e.target.blur();
      return;
    }
    dispatchKey(this.keys, e, toast); // a key that cannot act says why
  }

  /** The queue's keys: the one table the handler reads and the `?` overlay shows (keys.js). */
  keyTable() {
    return [
      { keys: ["j", "ArrowDown"], show: ["j", "↓"], does: "next row",
        run: () => (!this.rows.length ? "no system on this page"
          : this.selected >= this.rows.length - 1 ? (this.nextCursor ? "last row of this page: n for the next page" : "last system of the queue")
          : this.select(this.selected + 1)) },
      { keys: ["k", "ArrowUp"], show: ["k", "↑"], does: "previous row",
        run: () => (!this.rows.length ? "no system on this page"
          : this.selected <= 0 ? (this.prevCursor ? "first row of this page: p for the previous page" : "first system of the queue")
          : this.select(this.selected - 1)) },
      { keys: ["Enter"], does: "open the selected system",
        run: (e) => (e.target.closest?.("a, button") ? false
          : this.rows[this.selected] ? this.open(this.rows[this.selected].id) : "no system selected: j / k choose one") },
      { keys: ["n"], does: "next page", run: () => (this.nextCursor ? this.turnPage(1) : "this is the last page of the queue") },
      { keys: ["p"], does: "previous page", run: () => (this.prevCursor ? this.turnPage(-1) : "this is the first page of the queue") },
      { keys: ["/"], does: "filters (Esc to leave)", run: () => $("filter-status").focus() },
    ];
  }
}


new QueuePage();
