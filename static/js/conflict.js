// The conflict notice of the system page: a write answered 412 (someone, or the same user elsewhere, changed the
// resource since the page read it). It says who changed it and to what (the 412's last audit entry and current
// state; for the system's decision every change since the page's version, in words), what was not
// stored, and offers "re-apply my change" (the same write against the current version) or "keep
// theirs" (the page already shows their state).

import { getMe } from "./api.js";
import { el } from "./format.js";
import { describeEntry } from "./history.js";

/** Show the notice in `root` for a 412 `error` (ApiError; body {current, etag, last_change, changes_since}).
 * `what`: the resource in words ("V2 (2_1.png)"); `mine`: the change not stored, in words;
 * `reapply(etag)`: send it again against version `etag`; both buttons close the notice. */
export async function showConflict(root, { error, what, mine, viewName, reapply }) {
  const body = error.body || {};
  const last = body.last_change;
  const me = await getMe().then((m) => m.name, () => null);
  const who = last ? describeEntry(last, viewName) : "someone (no audit entry found)";
  const close = () => {
    root.hidden = true;
    root.replaceChildren();
  };
  // a decision's version covers every view of the system: what changed under the page, one line each
  const since = (body.changes_since || []).map((e) => el("li", {}, `${e.actor}: ${e.summary}`));
  root.replaceChildren(
    el("strong", {}, `Conflict: ${what} was changed ${byWhom(body, me)} since this page read it; your change was not stored.`),
    el("div", { "data-testid": "conflict-who" }, `Last change: ${who}`),
    ...(since.length ? [el("div", {}, "Since your page:"), el("ul", { "data-testid": "conflict-since" }, ...since)]
      : []),
    el("div", { "data-testid": "conflict-mine" }, `Your change: ${mine}`),
    el("div", { class: "actions" },
      el("button", { type: "button", "data-testid": "conflict-reapply",
        onclick: () => { close(); reapply(body.etag); } }, "Re-apply my change"),
      el("button", { type: "button", "data-testid": "conflict-keep", onclick: close }, "Keep theirs")),
  );
  root.hidden = false;
}

/** Who made the changes a 412 reports, in words: "by you (in another tab or window)" when every one was the user's
 * own, else the people by name (you among them when you were). */
export function byWhom(body, me) {
  const changes = body.changes_since?.length ? body.changes_since : body.last_change ? [body.last_change] : [];
  const actors = [...new Set(changes.map((e) => e.actor).filter(Boolean))];
  if (!actors.length) return "by someone else";
  if (me && actors.every((a) => a === me)) return "by you (in another tab or window)";
  return `by ${actors.map((a) => (a === me ? "you" : a)).join(" and ")}`;
}
