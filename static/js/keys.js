// One key table per page: the page's key handler dispatches through it (dispatchKey) and both the key
// card and the `?` overlay (data-testid="keys-help") are drawn from it (renderKeys), so what the page
// says and what it does cannot drift.
//
// An entry: { keys: [KeyboardEvent.key values it answers], show: [labels drawn for them, default the
// keys], does: "what it does", ctrl: true for a Ctrl (or Cmd) chord, run(e) -> false when the key was
// not used (the next entry answering it is tried), a string when it was not used and says why (the
// next entry is tried too; when none uses the key, the page is told why: every key answers), else it
// was used (its default is then prevented) }.
// Entries answer keys without Ctrl / Meta / Alt unless `ctrl`; Shift is the key's own business (e.key
// carries it).

import { el, isTyping } from "./format.js";
import { onWorkEnded, working } from "./busy.js";

/** Whether some entry of `table` answers `e` (its key, with or without Ctrl as the entry says): a key of the page,
 * not the browser's. */
export function answersKey(table, e) {
  if (e.altKey) return false;
  const chord = e.ctrlKey || e.metaKey;
  return table.some((entry) => entry.keys.includes(e.key) && Boolean(entry.ctrl) === chord);
}

/** How many keys typed ahead a page keeps (beyond it, a key is refused in words). */
export const KEYS_AHEAD = 8;

/** Keys typed while the page cannot act on them yet (a system loading, a write or an undo on its way, an answer not
 * taken in yet) are kept and applied in order once it can: `s` then `Enter` typed at once snaps the label and then
 * confirms the placement the snap's answer drew, as they would typed slowly. A key is applied at once only when no
 * key waits before it, so the order typed is the order applied. Beyond `bound` keys waiting, or when a queued key
 * would land in a text field that took the focus meanwhile, the page says so instead of losing the key silently.
 *
 * `answers(e)`: the key is one of the page's (other keys are the browser's and pass); `ready(e)`: the page can act
 * on the key now; `apply(e)`: act on it (the page's dispatch, which says why when it cannot act); `say(words)`: tell
 * the person (a toast). The queue is drained each time a piece of the page's work ends (busy.js); while keys wait,
 * the page is busy with "keys". */
export class KeyQueue {
  #waiting = [];
  #work = null;
  #draining = false;

  constructor({ answers, ready, apply, say, bound = KEYS_AHEAD }) {
    Object.assign(this, { answers, ready, apply, say, bound });
    // after the work that ended has finished its turn (its caller may begin the next piece at once)
    onWorkEnded(() => setTimeout(() => this.drain(), 0));
  }

  /** How many keys wait. */
  get length() {
    return this.#waiting.length;
  }

  /** A keydown of the page: applied now, or kept for later. */
  take(e) {
    if (!this.answers(e)) return;
    if (!this.#waiting.length && this.ready(e)) {
      this.apply(e);
      return;
    }
    e.preventDefault(); // kept: not the browser's either (an arrow key would scroll the page)
    if (this.#waiting.length >= this.bound) {
      this.say(`${keyName(e)} not taken: ${this.bound} keys already wait for the page to finish loading or saving`);
      return;
    }
    this.#waiting.push(e);
    this.#work ??= working("keys");
  }

  /** Apply the keys that wait, in order, while the page can act on them. */
  drain() {
    if (this.#draining) return;
    this.#draining = true;
    try {
      while (this.#waiting.length && this.ready(this.#waiting[0])) {
        if (isTyping({ target: document.activeElement })) { // a key before them focused a text field
          const n = this.#waiting.length;
          this.#waiting = [];
          this.say(`${n} key${n === 1 ? "" : "s"} typed ahead not applied: the focus is in a text field now`);
          break;
        }
        this.apply(this.#waiting.shift());
      }
    } finally {
      this.#draining = false;
    }
    if (!this.#waiting.length && this.#work) {
      const end = this.#work;
      this.#work = null;
      end();
    }
  }
}

/** A key as a person reads it: "Ctrl+Shift+Z", "Enter", "j". */
function keyName(e) {
  return [e.ctrlKey ? "Ctrl" : null, e.metaKey ? "Cmd" : null, e.shiftKey && (e.key.length > 1 || e.ctrlKey || e.metaKey) ? "Shift" : null, e.key]
    .filter(Boolean).join("+");
}

/** Run the entries of `table` that answer `e` in order until one uses it; true when one did. When none
 * did and one said why it could not (a string), `cannot(why)` is called with the last such reason (the key
 * is then taken too). */
export function dispatchKey(table, e, cannot = null) {
  if (e.altKey) return false;
  const chord = e.ctrlKey || e.metaKey;
  let why = null;
  for (const entry of table) {
    if (!entry.keys.includes(e.key) || Boolean(entry.ctrl) !== chord) continue;
    const used = entry.run(e);
    if (typeof used === "string") why = used;
    else if (used !== false) {
      e.preventDefault();
      return true;
    }
  }
  if (why !== null && cannot) {
    e.preventDefault();
    cannot(why);
    return true;
  }
  return false;
}

/** The table's rows as <kbd> + text pairs (for a `.keys` grid). */
export function keyRows(table) {
  return table.flatMap((entry) => {
    const shown = entry.show || entry.keys;
    const kbds = shown.flatMap((k, i) => (i ? [" / ", el("kbd", {}, k)] : [el("kbd", {}, k)]));
    return [el("span", { class: "key" }, kbds), el("span", {}, entry.does)];
  });
}

/** Fill `container` (a `.keys` or `.keys-grid` grid) with the table. */
export function renderKeys(table, container) {
  container.replaceChildren(...keyRows(table));
}

/**
 * The `?` overlay: a dialog listing every key of `table`, opened and closed by `?` (Escape or a click
 * outside closes it too), then `extra` (an element: the chips' legend, words.js chipLegend). Returns the
 * entry to add to the table.
 */
export function keysHelp(table, title = "Keys", extra = null) {
  const list = el("div", { class: "keys-grid" });
  const dialog = el("dialog", { class: "keys-help", "data-testid": "keys-help", "aria-label": title },
    el("h2", {}, title), list, extra, el("p", { class: "muted" }, "? or Esc to close"));
  dialog.addEventListener("click", (e) => { if (e.target === dialog) dialog.close(); });
  dialog.addEventListener("keydown", (e) => {
    // Chromium may still send a key to the dialog just after Esc closed it (focus goes back a moment later):
    // such a key is the page's, not the closed list's
    if (!dialog.open) return;
    e.stopPropagation(); // the page's keys wait while the list is open
    if (e.key === "?") {
      e.preventDefault();
      dialog.close();
    }
  });
  document.body.append(dialog);
  return {
    keys: ["?"],
    does: "this list of keys",
    run: () => {
      if (dialog.open) dialog.close();
      else {
        renderKeys(table, list);
        dialog.showModal();
      }
    },
  };
}
