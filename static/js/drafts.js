// Text a person typed and has not sent yet (a decision's comment, a comment being pinned). A page names each of its
// drafts (`keepDraft(name, read, write)`). When the session ends under the page (a 401: api.js takes the person to
// the login page and back here), the drafts are kept in the tab's sessionStorage under the page's path
// (`keepDrafts`) and put back once the page is open again (`restoreDrafts`); any other way of leaving the page with
// a draft (a reload, a link, closing the tab) is warned by the browser first (beforeunload), since nothing keeps it.

const KEY = "v3d.drafts";
/** name -> {read: () => the draft (any JSON value) or null when there is none, write: (draft) => put it back} */
const DRAFTS = new Map();
let kept = false; // the drafts are kept for the login's return: leaving then loses nothing, so no warning

/** Name a draft of this page: `read()` answers it (null: nothing typed), `write(draft)` puts a kept one back. */
export function keepDraft(name, read, write) {
  DRAFTS.set(name, { read, write });
}

function typed() {
  const out = {};
  for (const [name, { read }] of DRAFTS) {
    const draft = read();
    if (draft !== null && draft !== undefined) out[name] = draft;
  }
  return out;
}

function stored() {
  try {
    return JSON.parse(sessionStorage.getItem(KEY) || "{}") || {};
  } catch {
    return {};
  }
}

/** Keep this page's drafts for its return after the login (the session ended); answers whether there were any. */
export function keepDrafts() {
  kept = true;
  const drafts = typed();
  if (!Object.keys(drafts).length) return false;
  try {
    sessionStorage.setItem(KEY, JSON.stringify({ ...stored(), [location.pathname]: drafts }));
  } catch {
    return false; // storage refused (full, or disabled): the login page says nothing was kept
  }
  return true;
}

/** Put back the drafts kept for this page when its session ended (each once); answers the names put back. */
export function restoreDrafts() {
  const all = stored();
  const drafts = all[location.pathname];
  if (!drafts) return [];
  delete all[location.pathname];
  sessionStorage.setItem(KEY, JSON.stringify(all));
  const back = [];
  for (const [name, draft] of Object.entries(drafts)) {
    const named = DRAFTS.get(name);
    if (named) {
      named.write(draft);
      back.push(name);
    }
  }
  watch();
  return back;
}

function warn(event) {
  if (kept || !Object.keys(typed()).length) return;
  event.preventDefault();
  event.returnValue = ""; // the browser's own words: text typed here would be lost
}

/** The warning is listened for only while there is a draft: a page with a beforeunload listener has the browser
 * ask its script before every navigation away, which a page with nothing typed has no reason to. */
function watch() {
  if (Object.keys(typed()).length) window.addEventListener("beforeunload", warn);
  else window.removeEventListener("beforeunload", warn);
}

document.addEventListener("input", watch, true);
