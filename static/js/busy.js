// What the page is working on, said where a person's tools and the browser tests can read it: <body data-busy="load
// save"> names the kinds of work under way (a request the page made and waits for, a system loading, a write on its
// way, an undo, a key typed ahead and not applied yet, a nudge waiting for its pause, a frame's image arriving); the
// attribute is absent only when none is. Work that only keeps the page fresh (a heartbeat, a poll of the jobs, the
// next system's images warmed up) is not counted: it never ends, and nothing a person does waits for it. Waiting for
// a person (a dialog asking them) is not work either.
//
// The system page's key queue (keys.js KeyQueue) asks `busyWith` whether a key can act now, and is told by
// `onWorkEnded` when the work it waits for is over.

/** kind -> how many pieces of that kind are under way */
const work = new Map();
const listeners = new Set();

function show() {
  const kinds = [...work.keys()].sort();
  if (kinds.length) document.body.dataset.busy = kinds.join(" ");
  else delete document.body.dataset.busy;
}

/** Begin a piece of work of `kind`; answers the function that ends it (calling it again does nothing). */
export function working(kind) {
  work.set(kind, (work.get(kind) || 0) + 1);
  show();
  let ended = false;
  return () => {
    if (ended) return;
    ended = true;
    const left = (work.get(kind) || 1) - 1;
    if (left > 0) work.set(kind, left);
    else work.delete(kind);
    show();
    for (const fn of [...listeners]) fn(kind);
  };
}

/** `promise`, counted as work of `kind` until it settles (whichever way). */
export function whileWorking(kind, promise) {
  const end = working(kind);
  Promise.resolve(promise).then(end, end);
  return promise;
}

/** The kinds of work among `kinds` under way now (all kinds when `kinds` is omitted). */
export function busyWith(kinds = null) {
  return [...work.keys()].filter((k) => !kinds || kinds.includes(k));
}

/** Call `fn(kind)` each time a piece of work ends (after the attribute says so). */
export function onWorkEnded(fn) {
  listeners.add(fn);
}
