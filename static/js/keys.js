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

import { el } from "./format.js";

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
