// Audit page (static/audit.html, linked for admins): the whole audit log (GET /api/audit), newest first, one row per
// entry with its number (what a history's "undo of entry N" names), when, who, the action, the system (a link to its
// page) and the change in words (the entry's summary). Filters by who, by system and by the reader's days (from,
// until: local midnights sent as `since` / `until`), and pages of `limit` entries by the API's `next_offset`; the
// filters and the page are kept in the address bar, so a filtered page can be linked and reloaded.
import { getMe, latestWins, listAudit, send, toQuery } from "./api.js";
import "./session.js";
import { el, fmtWhen, fmtCount, showError, clearError } from "./format.js";

const $ = (id) => document.querySelector(`[data-testid=${id}]`);
/** Entries per page unless the address says otherwise (the API's default). */
const PAGE = 50;
/** The filters the address bar keeps, by the form's field names. */
const FILTERS = ["user", "system", "from", "until"];

/** The filters and the page, from the address bar. */
function stateOf(search = location.search) {
  const q = new URLSearchParams(search);
  const state = Object.fromEntries(FILTERS.map((k) => [k, q.get(k) ?? ""]));
  state.offset = Math.max(0, Number(q.get("offset")) || 0);
  state.limit = Math.min(500, Math.max(1, Number(q.get("limit")) || PAGE));
  return state;
}

/** `state` in the address bar (history: a new entry per page, so Back returns to the page before). */
function keep(state) {
  const q = new URLSearchParams();
  for (const k of FILTERS) if (state[k]) q.set(k, state[k]);
  if (state.offset) q.set("offset", String(state.offset));
  if (state.limit !== PAGE) q.set("limit", String(state.limit));
  const search = q.toString() ? `?${q}` : "";
  if (search !== location.search) history.pushState(null, "", `${location.pathname}${search}`);
}

/** The local midnight starting the day `yyyy-mm-dd` (plus `days`), as the API's UTC time. */
export function localMidnight(day, days = 0) {
  const [y, m, d] = day.split("-").map(Number);
  return new Date(y, m - 1, d + days).toISOString();
}

/** The API's query of `state`: the days as the reader's midnights, `until` including its day. */
export function apiQuery(state) {
  return {
    user: state.user || null,
    system_id: state.system || null,
    since: state.from ? localMidnight(state.from) : null,
    until: state.until ? localMidnight(state.until, 1) : null,
    limit: state.limit,
    offset: state.offset,
  };
}

/** Who made the entry, in words: work run on the machine is the command line. */
function who(actor) {
  if (actor === "cli") return "command line";
  if (actor.startsWith("cli:")) return `command line (${actor.slice(4)})`;
  return actor;
}

function entryRow(entry) {
  // an audit is read by its dates: the local date and time shown, how long ago on hover
  const { text: ago } = fmtWhen(entry.at);
  const at = new Date(entry.at);
  const system = entry.system_id == null
    ? el("span", { class: "muted" }, "—")
    : el("a", { href: `/systems/${entry.system_id}`, "data-testid": "audit-system-link" }, String(entry.system_id));
  const what = el("td", { class: "what", "data-testid": "audit-summary" }, entry.summary || entry.action);
  if (entry.reverts_id != null) {
    what.append(" ", el("a", { href: `#entry-${entry.reverts_id}`, "data-testid": "audit-reverts",
      title: `entry ${entry.reverts_id}, the one this entry undoes (when it is on this page)` }, `→ #${entry.reverts_id}`));
  }
  return el("tr", { id: `entry-${entry.id}`, "data-testid": "audit-row", "data-id": entry.id },
    el("td", { class: "num", "data-testid": "audit-id" }, `#${entry.id}`),
    el("td", { class: "when" }, el("time", { datetime: entry.at, title: ago },
      at.toLocaleString(undefined, { dateStyle: "medium", timeStyle: "medium" }))),
    el("td", { "data-testid": "audit-actor" }, who(entry.actor)),
    el("td", {}, el("code", {}, entry.action)),
    el("td", { class: "num", "data-testid": "audit-system-id" }, system),
    what);
}

/** An answer is shown only while its page is still the latest asked (two pages asked in quick succession may be
 * answered in either order, and the rows must be the filters' and the page's the form says). */
const askPage = latestWins();

async function show(state) {
  const form = $("audit-filters");
  for (const k of FILTERS) form.elements[k].value = state[k];
  const latest = askPage();
  let page;
  try {
    page = await listAudit(apiQuery(state));
  } catch (e) {
    if (latest()) showError(e.message);
    return;
  }
  if (!latest()) return;
  clearError();
  const table = $("audit");
  table.querySelector("tbody").replaceChildren(...page.items.map(entryRow));
  table.dataset.shown = toQuery(apiQuery(state));  // which query the rows answer (a test waits on it)
  $("audit-empty").hidden = page.items.length > 0;
  const first = page.items.length ? state.offset + 1 : 0;
  const last = state.offset + page.items.length;
  $("audit-count").textContent = `${fmtCount(page.total)} entr${page.total === 1 ? "y" : "ies"}`
    + (FILTERS.some((k) => state[k]) ? " match the filters" : " in all");
  $("audit-page").textContent = page.items.length ? `entries ${fmtCount(first)}–${fmtCount(last)} of ${fmtCount(page.total)}` : "";
  const newer = $("audit-newer");
  const older = $("audit-older");
  newer.disabled = state.offset === 0;
  older.disabled = page.next_offset == null;
  newer.onclick = () => go({ ...state, offset: Math.max(0, state.offset - state.limit) });
  older.onclick = () => go({ ...state, offset: page.next_offset });
}

function go(state) {
  keep(state);
  return show(state);
}

/** The names the Who field offers: the users (an admin's list: the other roles type a name) and the command line. */
async function offerPeople() {
  const me = await getMe();
  const names = me.role === "admin" ? (await send("GET", "/api/users")).map((u) => u.name) : [];
  $("audit-people").replaceChildren(...[...names, "cli"].map((n) => el("option", { value: n })));
}

function mount() {
  $("error-dismiss").addEventListener("click", clearError);
  const form = $("audit-filters");
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    const state = { ...stateOf(), offset: 0 };
    for (const k of FILTERS) state[k] = String(form.elements[k].value).trim();
    go(state);
  });
  $("audit-clear").addEventListener("click", () => go({ ...Object.fromEntries(FILTERS.map((k) => [k, ""])), offset: 0, limit: stateOf().limit }));
  window.addEventListener("popstate", () => show(stateOf()));
  offerPeople().catch((e) => showError(e.message));
  return show(stateOf());
}

mount().catch((e) => showError(e.message));
