// Every key of the system page answers: a key that cannot act says why in a toast instead of
// doing nothing. The reasons live here, by key, apart from the key table (system.js keyTable and the
// entries of viewdecisions.js, zoom.js and lineseditor.js): `explainKeys(table, page)` wraps the last entry
// answering each key with its reason, checked before the entry runs (`before`: the entry would act on
// nothing, or would act without effect) and after it declined (`after`), and dispatchKey (keys.js) tells
// the page the reason when no entry used the key. Undo and redo (Ctrl+Z, Ctrl+Shift+Z, Ctrl+Y) need no reason
// here: the page's undo stack (system.js, EditHistory) says itself when it has nothing to undo or redo.

import { FIX_KEY, FIX_LABEL, isMirrorFlagged } from "./viewfacts.js";
import { inASequence } from "./sequence.js";

const SELECT_FIRST = "select a view first (1…9)";

/** The reasons of the system page's keys: [keys, ctrl, {before(e), after(e)}]; each returns a reason or null. */
function reasons(page) {
  const panels = () => [...(document.querySelector('[data-testid="views"]')?.children || [])];
  const view = () => panels()[page.selected] || null;
  const name = (panel) => `V${panels().indexOf(panel) + 1}`;
  const loading = () => (!page.system ? "the system is still loading" : null);
  const busy = () => loading() || (page.busy ? "wait: the page is still loading or saving" : null);
  const needView = () => loading() || (view() ? null : SELECT_FIRST);
  const saving = () => {
    const panel = view();
    return panel ? `${name(panel)} is still saving its last edit` : SELECT_FIRST;
  };
  const hasLabel = (panel) => Boolean(panel?.view?.ball?.kind);
  const noLabel = (verb) => () => {
    const panel = view();
    if (!panel) return SELECT_FIRST;
    return hasLabel(panel) ? saving() : `${name(panel)} has no ball label to ${verb} (click in the view to place one)`;
  };
  const pass = page.pass;
  const editor = () => view()?.lines || null;
  const notEditing = (what) => () => {
    if (!view()) return `${what}: select a view (1…9), then press e to edit its field lines`;
    return editor()?.editing ? what : `${what}: press e to edit ${name(view())}'s field lines first`;
  };
  const viewDecision = () => loading() || (view() || page.system.views.length === 1 ? null : SELECT_FIRST);
  const zoomed = () => (page.zoom?.state?.z ?? 1) > 1;

  return [
    [["a", "r", "f"], false, { before: busy }],
    // page.stepId: the pass's neighbours once the shown system's place is known, the queue's until then (a place
    // still of the system shown before must not answer for this one)
    [["j"], false, { before: () => busy() || (page.stepId(1) == null
      ? (pass?.place ? "this is the last system of the pass (u: back to the queue)" : "this is the last system of the queue") : null) }],
    [["k"], false, { before: () => busy() || (page.stepId(-1) == null
      ? (pass?.place ? "this is the first system of the pass" : "this is the first system of the queue") : null) }],
    [[",", "."], false, { before: (e) => loading() || (!inASequence(page.system)
      ? "only the frames of an ISSIA sequence have a frame before and after"
      : page.sequence.neighbour(e.key === "." ? 1 : -1) == null
        ? `this is the ${e.key === "." ? "last" : "first"} frame of the sequence` : null),
    after: () => "only the frames of an ISSIA sequence have a frame before and after" }],
    [["1", "2", "3", "4", "5", "6", "7", "8", "9"], false, { before: (e) => {
      const n = page.system?.views.length ?? 0;
      return loading() || (Number(e.key) > n ? `this system has ${n} view${n === 1 ? "" : "s"}: ${e.key} selects none` : null);
    } }],
    [["ArrowLeft", "ArrowUp", "ArrowRight", "ArrowDown", "+", "="], false, { before: needView, after: noLabel("move") }],
    [["-"], false, { before: needView, after: () => (hasLabel(view()) ? `${name(view())}'s box cannot shrink further (or is still saving)` : noLabel("shrink")()) }],
    [["Delete", "Backspace"], false, { before: needView, after: noLabel("remove") }],
    [["z"], false, { before: needView, after: () => {
      const panel = view();
      if (!panel) return SELECT_FIRST;
      return panel.view?.ball?.edited ? saving() : `${name(panel)}'s ball label is as imported: nothing to restore`;
    } }],
    [["s"], false, { before: () => {
      if (loading()) return loading();
      if (page.fixTarget()) return null;
      // s only snaps: a view whose fix is another key's is told which key
      const other = (p) => {
        const key = FIX_KEY[p?.fixableDoubt()?.suggestion?.action];
        return key && key !== "s" ? `${name(p)}'s fix is “${FIX_LABEL[p.fixableDoubt().suggestion.action]}”: press ${key} (s only snaps a label)` : null;
      };
      if (page.selected >= 0) return other(view()) || `${name(view())} has no doubt with a suggested fix to snap to`;
      const fixable = panels().filter((p) => p.fixableDoubt("s"));
      if (fixable.length) return `${fixable.length} views have a suggested box: select one (1…9)`;
      const others = panels().map(other).filter(Boolean);
      return others.length ? others.join("; ") : "no doubt of this system has a suggested fix to snap to";
    }, after: saving }],
    [["x"], false, { before: () => loading() || (page.system.views.length === 1
      ? "a single view has no 3D ball to exclude it from" : view() ? null : `${SELECT_FIRST} to exclude it`),
    after: saving }],
    [["m"], false, { before: () => {
      if (loading()) return loading();
      const panel = page.mirrorTarget();
      if (panel && panel.view && isMirrorFlagged(panel.view)) return null;
      if (panel) return `${name(panel)} is not flagged as mirrored: nothing to mirror`;
      const flagged = panels().filter((p) => p.view && isMirrorFlagged(p.view)).length;
      return flagged ? `${flagged} views are flagged as mirrored: select one (1…9)` : "no view of this system is flagged as mirrored";
    }, after: saving }],
    [["A", "R", "F", "G", "B", "N"], false, { before: viewDecision, after: saving }],
    [["e"], false, { before: () => loading() || (view() ? null : `${SELECT_FIRST} to edit its field lines`) }],
    [["[", "]"], false, { after: notEditing("no class to choose") }],
    [["l"], false, { after: notEditing("nothing to relabel: select a line, then choose its class with [ ]") }],
    [["n"], false, { after: notEditing("no new line now: choose a class with [ ] first") }],
    // Enter's main use is confirming a label placed from a doubt's fix; a line being drawn is its other
    [["Enter"], false, { after: () => "nothing to confirm: no label placed from a doubt's fix waits for you (s places one), and no line is being drawn" }],
    [["Escape"], false, { after: () => "nothing to cancel" }],
    [[">", "<"], false, { before: (e) => {
      const z = page.zoom?.state?.z ?? 1;
      if (e.key === "<" && z <= 1) return "the views already show the whole frames";
      if (e.key === ">" && z >= 64) return "the views are zoomed in as far as they go";
      return null;
    } }],
    [["0"], false, { before: () => (zoomed() ? null : "the views already show the whole frames") }],
    [["I", "J", "K", "L"], false, { before: () => (zoomed() ? null : "zoom in first (>) to pan"), after: () => "zoom in first (>) to pan" }],
  ];
}

/** `table` with the reasons of `page`'s keys added to the last entry answering each key (keys.js). */
export function explainKeys(table, page) {
  const found = reasons(page);
  const reasonOf = (key, ctrl) => found.find(([keys, c]) => c === ctrl && keys.includes(key))?.[2] || null;
  const last = new Map();
  table.forEach((entry, i) => entry.keys.forEach((k) => last.set(`${Boolean(entry.ctrl)}:${k}`, i)));
  return table.map((entry, i) => ({
    ...entry,
    run: (e) => {
      const ctrl = Boolean(entry.ctrl);
      const reason = last.get(`${ctrl}:${e.key}`) === i ? reasonOf(e.key, ctrl) : null;
      if (!reason) return entry.run(e);
      const why = reason.before?.(e);
      if (why) return why;
      const used = entry.run(e);
      return used === false ? reason.after?.(e) || false : used;
    },
  }));
}
