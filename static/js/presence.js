// Presence and assignment on the system page: who the system is assigned to (a chip in the
// header) and who else has it open now ("ana has this system open (since 2 min)", a warning bar under the
// header, shown before you edit), so that two people rarely edit one system at once.
//
// While the page shows a system it sends a heartbeat, PUT /api/systems/{id}/presence, every
// `heartbeat_seconds` (10 s): a soft claim that lapses 50 s after its last refresh. The server writes the
// claim only when it is due (at most once per 30 s), so an open page costs two database writes a minute;
// the other heartbeats only read who else is there. Leaving the system (another system, the queue, closing the
// tab: `pagehide`) ends the claim at once (DELETE, sent with keepalive); a page that vanishes lapses by itself.
// The others' "since N s" counts on every second between heartbeats; a claim that ended leaves the bar at the
// next heartbeat.

import { getMe, send, CSRF_HEADER } from "./api.js";
import { el } from "./format.js";

const DEFAULT_HEARTBEAT_S = 20;

/** "since 2 min" / "since 40 s" / "since 1 h 5 min" from seconds. */
export function sinceWords(seconds) {
  const s = Math.max(0, Math.round(seconds || 0));
  if (s < 60) return `since ${s} s`;
  const min = Math.floor(s / 60);
  if (min < 60) return `since ${min} min`;
  return `since ${Math.floor(min / 60)} h ${min % 60} min`;
}

/** "ana has this system open (since 2 min)", or "ana and ben have this system open (ana since 2 min, ...)". */
export function presenceWords(others) {
  if (!others.length) return "";
  if (others.length === 1) return `${others[0].name} has this system open (${sinceWords(others[0].seconds_open)})`;
  const names = others.map((p) => p.name);
  const list = `${names.slice(0, -1).join(", ")} and ${names[names.length - 1]}`;
  return `${list} have this system open (${others.map((p) => `${p.name} ${sinceWords(p.seconds_open)}`).join(", ")})`;
}

export class SystemPresence {
  /** `anchor`: the header element after which the assignee chip goes; the warning bar goes after the header. */
  constructor(anchor) {
    this.systemId = null;
    this.timer = null;
    this.heartbeatMs = DEFAULT_HEARTBEAT_S * 1000;
    this.chip = el("span", { class: "chip info assignee", "data-testid": "system-assignee", hidden: "" });
    anchor.after(this.chip);
    this.bar = el("div", { class: "presence-bar", "data-testid": "presence", role: "status", hidden: "" });
    document.querySelector(".topbar").after(this.bar);
    this.me = getMe().catch(() => null);
    window.addEventListener("pagehide", () => this.release(true));
    document.addEventListener("visibilitychange", () => {
      if (document.visibilityState === "visible" && this.systemId !== null) this.beat();
    });
  }

  /** Draw a system view's `assignment` and `open_by` (called with every render); a new system moves the claim. */
  async show(sys) {
    const me = await this.me;
    this.myName = me?.name ?? null;
    this.csrf = me?.csrf_token ?? null;
    this.drawAssignee(sys.assignment);
    this.drawOthers((sys.open_by || []).filter((p) => p.name !== this.myName));
    if (sys.id !== this.systemId) {
      this.release(false);
      this.systemId = sys.id;
      this.beat();
    }
  }

  drawAssignee(a) {
    const who = a?.assignee;
    this.chip.hidden = !who;
    if (!who) return;
    const mine = who === this.myName;
    this.chip.textContent = mine ? "assigned to you" : `assigned to ${who}`;
    this.chip.classList.toggle("mine", mine);
    this.chip.title = `assigned to ${who}${a.assigned_by ? ` by ${a.assigned_by}` : ""}${a.assigned_at ? ` on ${new Date(a.assigned_at).toLocaleString()}` : ""}`;
  }

  /** Show who else has the system open (their `seconds_open` as of now); the seconds then count on locally. */
  drawOthers(others) {
    this.others = others;
    this.seenAt = performance.now();
    clearInterval(this.ticker);
    this.ticker = null;
    this.bar.hidden = !others.length;
    if (!others.length) return;
    this.drawWords();
    this.bar.dataset.names = others.map((p) => p.name).join(",");
    this.ticker = setInterval(() => this.drawWords(), 1000);
  }

  drawWords() {
    const elapsed = (performance.now() - this.seenAt) / 1000;
    const now = this.others.map((p) => ({ ...p, seconds_open: (p.seconds_open || 0) + elapsed }));
    this.bar.replaceChildren(
      el("b", {}, presenceWords(now)),
      el("span", {}, ": your edits may cross theirs. Agree who goes on, or pick another system."),
    );
  }

  /** One heartbeat now, then every `heartbeat_seconds` while the system stays shown. */
  async beat() {
    clearTimeout(this.timer);
    const id = this.systemId;
    if (id === null) return;
    try {
      const answer = await send("PUT", `/api/systems/${encodeURIComponent(id)}/presence`, { background: true });
      if (id !== this.systemId) return; // moved on meanwhile
      this.heartbeatMs = Math.max(5, answer.heartbeat_seconds || DEFAULT_HEARTBEAT_S) * 1000;
      this.drawOthers(answer.others || []);
    } catch {
      // presence is a hint: a failed heartbeat only means others may not see us for a while
    }
    if (id === this.systemId) this.timer = setTimeout(() => this.beat(), this.heartbeatMs);
  }

  /** End the claim on the current system (`leaving`: the page is going away, so the request must outlive it). */
  release(leaving) {
    clearTimeout(this.timer);
    const id = this.systemId;
    if (id === null) return;
    this.systemId = null;
    const url = `/api/systems/${encodeURIComponent(id)}/presence`;
    if (leaving) { // synchronously: the page is going away
      const headers = this.csrf ? { [CSRF_HEADER]: this.csrf } : {};
      fetch(url, { method: "DELETE", keepalive: true, credentials: "same-origin", headers }).catch(() => {});
    } else {
      send("DELETE", url, { background: true }).catch(() => {});
    }
  }
}
