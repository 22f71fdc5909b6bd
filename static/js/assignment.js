// Work assignment on the queue page: the "My systems" toggle (the queue of the systems
// assigned to me: GET /api/systems?assignee=me), each row's assignee and who has it open now, and, for
// reviewers and admins, the bar that assigns systems (POST /api/assignments): the selected system, its game,
// or every system the current filters match (all pages), to a person, or to nobody.

import { getMe, send } from "./api.js";
import { apiFilters } from "./queuestate.js";
import { el, showError } from "./format.js";
import { sinceWords } from "./presence.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);
/** How often the queue re-reads who has its rows open (one read of the page's rows; nothing is written). */
const PEOPLE_REFRESH_MS = 30000;

/** The queue filters as the body of an assignment by filter (numbers as numbers, no sort, no empty value). */
export function filterBody(state) {
  const out = {};
  for (const [k, v] of Object.entries(apiFilters(state))) {
    if (v === "" || v === undefined || v === null || k === "sort") continue;
    out[k] = ["game_id", "jac_min", "jac_max", "error_min", "error_max", "sigma_min", "sigma_max"].includes(k) ? Number(v) : v;
  }
  return out;
}

export class QueueAssignment {
  /** `page`: the queue page (its `state`, `rows`, `selected`, `total`, `firstPage()`, `navigate()`, `load()`);
   * `params()`: the query of GET /api/systems for the page shown (to refresh its rows' people). */
  constructor(page, params) {
    this.page = page;
    this.params = params;
    setInterval(() => this.refreshPeople(), PEOPLE_REFRESH_MS);
    this.myName = null;
    const form = $("filters");
    // the filter's form field (the queue reads every filter from the form), driven by the toggle
    this.input = el("input", { type: "hidden", name: "assignee" });
    this.toggle = el("button", { type: "button", class: "toggle", "data-testid": "my-systems", "aria-pressed": "false",
      title: "Only the systems assigned to you (?assignee=me)" }, "My systems");
    this.toggle.addEventListener("click", () => this.toggleMine());
    form.querySelector('[data-testid="apply"]').before(this.input, this.toggle);
    getMe().then((me) => {
      this.myName = me?.name ?? null;
      if ((me?.roles || []).includes("reviewer")) this.buildBar();
      if (this.page.rows?.length) this.page.renderRows(); // the rows came first: mark "yours" now
    }).catch(() => {});
  }

  /** Show the state's assignee filter on the toggle (called after every load). */
  update() {
    const a = this.page.state.assignee || "";
    this.input.value = a;
    this.toggle.setAttribute("aria-pressed", String(a === "me"));
    this.toggle.classList.toggle("on", a === "me");
    if (this.count) this.count.textContent = String(this.page.total);
    if (this.forGame) {
      const row = this.page.rows[this.page.selected];
      this.forGame.disabled = !row;
      this.forSelected.disabled = !row;
    }
  }

  /** Re-read the shown page's rows and redraw only their assignee and presence chips (while the tab is seen). */
  async refreshPeople() {
    if (document.visibilityState !== "visible" || !this.page.rows.length) return;
    let answer;
    try {
      answer = await send("GET", `/api/systems?${new URLSearchParams(
        Object.entries(this.params()).filter(([, v]) => v !== "" && v !== undefined && v !== null))}`, { background: true });
    } catch {
      return; // a hint only: the next load shows the truth
    }
    for (const s of answer.items || []) {
      const row = this.page.rows.find((r) => r.id === s.id);
      const cell = document.querySelector(`[data-testid="queue-row"][data-id="${s.id}"] [data-testid="system-link"]`)?.parentElement;
      if (!row || !cell) continue;
      Object.assign(row, { assignment: s.assignment, open_by: s.open_by });
      cell.querySelector(".people")?.remove();
      const chips = this.chips(s);
      if (chips) cell.append(chips);
    }
  }

  toggleMine() {
    this.page.state.assignee = this.page.state.assignee === "me" ? "" : "me";
    this.page.firstPage();
    this.page.navigate();
  }

  /** A row's assignee and the people who have it open (not me), as chips under its name. */
  chips(s) {
    const out = [];
    const who = s.assignment?.assignee;
    if (who) {
      const mine = who === this.myName;
      out.push(el("span", { class: `chip info assignee${mine ? " mine" : ""}`, "data-testid": "row-assignee",
        title: `assigned to ${who}${s.assignment.assigned_by ? ` by ${s.assignment.assigned_by}` : ""}` },
      mine ? "yours" : `→ ${who}`));
    }
    for (const p of (s.open_by || []).filter((x) => x.name !== this.myName)) {
      out.push(el("span", { class: "chip presence", "data-testid": "row-presence", "data-name": p.name,
        title: `${p.name} has this system open (${sinceWords(p.seconds_open)})` }, `${p.name} has it open`));
    }
    return out.length ? el("div", { class: "people" }, out) : null;
  }

  async buildBar() {
    let users = [];
    try {
      users = await send("GET", "/api/assignees");
    } catch (err) {
      showError(`assignees: ${err.message}`);
      return;
    }
    this.user = el("select", { "data-testid": "assign-user", "aria-label": "assign to" },
      el("option", { value: "" }, "nobody (unassign)"),
      users.map((u) => el("option", { value: u.name }, `${u.name} (${u.role})`)));
    this.forSelected = el("button", { type: "button", "data-testid": "assign-selected",
      title: "The selected row's system" }, "selected system");
    this.forGame = el("button", { type: "button", "data-testid": "assign-game",
      title: "Every system of the selected row's game" }, "its game");
    this.count = el("b", {}, "–");
    this.forFilter = el("button", { type: "button", "data-testid": "assign-filter",
      title: "Every system that matches the filters, on every page" }, "all ", this.count, " matching");
    this.result = el("span", { class: "muted", "data-testid": "assign-result", "aria-live": "polite" });
    this.forSelected.addEventListener("click", () => {
      const row = this.page.rows[this.page.selected];
      if (row) this.assign({ system_ids: [row.id] }, `${row.name}`);
    });
    this.forGame.addEventListener("click", () => {
      const row = this.page.rows[this.page.selected];
      if (row) this.assign({ game_id: row.game?.id }, `every system of ${row.game?.match || "its game"}`);
    });
    this.forFilter.addEventListener("click", () => {
      const n = this.page.total;
      const who = this.user.value || "nobody";
      if (n > 1 && !confirm(`Assign all ${n} systems that match the filters to ${who}?`)) return;
      this.assign({ filter: filterBody(this.page.state) }, `${n} matching system(s)`);
    });
    const bar = el("div", { class: "assign-bar", "data-testid": "assign-bar" },
      el("span", {}, "Assign"), this.forSelected, this.forGame, this.forFilter, el("span", {}, "to"), this.user,
      this.result);
    $("filters").after(bar);
    this.update();
  }

  async assign(selection, what) {
    const assignee = this.user.value || null;
    this.result.textContent = "…";
    try {
      const done = await send("POST", "/api/assignments", {
        headers: { "Content-Type": "application/json" }, body: JSON.stringify({ assignee, ...selection }),
      });
      this.result.textContent = `${what}: ${done.changed} of ${done.matched} now ${assignee ? `assigned to ${assignee}` : "unassigned"}`;
      this.page.load();
    } catch (err) {
      this.result.textContent = "";
      showError(`assign: ${err.message}`);
    }
  }
}
