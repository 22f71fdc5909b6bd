// REST client: every request the pages make goes through here, so the contract lives in one file.
// Writes are conditional: they send If-Match with the ETag of the version they were made against
// (a view's `etag`, the system view's `etag`) and answer {body, etag} with the resource's new ETag.
// A stale one fails with ApiError status 412, whose body holds {current, etag, last_change}.

import { keepDrafts } from "./drafts.js";
import { whileWorking } from "./busy.js";

export class ApiError extends Error {
  constructor(status, message, body) {
    super(message);
    this.name = "ApiError";
    this.status = status;
    this.body = body;
  }
}

/** FastAPI answers errors as {"detail": str} or {"detail": [{loc, msg}, ...]}: make one readable line. */
function describeError(status, body, fallback) {
  const detail = body && typeof body === "object" ? body.detail ?? body.message : null;
  let text;
  if (typeof detail === "string") text = detail;
  else if (Array.isArray(detail)) {
    text = detail
      .map((d) => {
        const where = Array.isArray(d.loc) ? d.loc.filter((p) => p !== "body" && p !== "query").join(".") : "";
        const msg = String(d.msg ?? "").replace(/^Value error, /, "");
        return where ? `${where}: ${msg}` : msg;
      })
      .join("; ");
  } else if (detail) text = JSON.stringify(detail);
  else text = fallback;
  return `${status}: ${text}`;
}

/** Methods that change something: a browser session must send its CSRF token with them. */
const UNSAFE = new Set(["POST", "PUT", "PATCH", "DELETE"]);
/** The header, and the page a person logs in on (docs/api.md, "Users, roles and the authentication layer"). */
export const CSRF_HEADER = "X-CSRF-Token";
export const LOGIN_PAGE = "/login";

let mePromise = null;
/** Set once this page had a session: a later 401 means that session ended (the login page says so). */
let hadSession = false;
/** Set while the person logs out: the page's other calls answered 401 then must not send the person to the login
 * page with this page to come back to (the log-out goes to the plain login page itself). */
let leaving = false;

/** GET /api/auth/me, asked once per page: {name, role, via, csrf_token}. A 401 sends the person to
 * the login page (and back here afterwards). */
export function getMe() {
  if (!mePromise) {
    mePromise = request("GET", "/api/auth/me").then((me) => {
      hadSession = true;
      return me;
    }, (err) => {
      mePromise = null;
      throw err;
    });
  }
  return mePromise;
}

/** Where the login page sends the person back to: this page, with its query string; `ended`: the page's session
 * ended under it (the login page says so), `kept`: the text typed there is kept and put back (drafts.js). */
export function loginUrl(next = location.pathname + location.search + location.hash, { ended = false, kept = false } = {}) {
  return `${LOGIN_PAGE}?next=${encodeURIComponent(next)}${ended ? "&ended=1" : ""}${kept ? "&kept=1" : ""}`;
}

/** Headers every write carries: the session's CSRF token. */
export async function writeHeaders() {
  const me = await getMe();
  return me.csrf_token ? { [CSRF_HEADER]: me.csrf_token } : {};
}

/** True for the API calls that need a session (not the login's own, not the health check) from a page that needs
 * one (not the login page). */
function needsSession(url) {
  return url.startsWith("/api/") && !url.startsWith("/api/auth/") && !url.startsWith("/api/health")
    && location.pathname !== LOGIN_PAGE;
}

/** A 401 means the session is gone (or never was): go and log in, then come back, the page's drafts kept. */
function toLogin() {
  if (leaving || location.pathname === LOGIN_PAGE) return;
  leaving = true; // the page's other calls answered 401 meanwhile go nowhere else
  location.assign(loginUrl(undefined, { ended: hadSession, kept: keepDrafts() }));
}

/** fetch with the CSRF header on writes (unless `init.csrf` is false: the login, before any session)
 * and the 401 rule; `init.body` as given (JSON text or FormData). Answers {body (parsed), etag (the
 * answer's ETag header: a write's edited resource's new version), entry (X-V3D-Audit-Entry: the
 * audit entry of the write, else null)}, or throws ApiError. The request is the page's work (busy.js) until it is
 * answered, unless `init.background` says it only keeps the page fresh (a poll, a heartbeat, a warm-up). */
function fetchJson(method, url, { background = false, ...init } = {}) {
  const answer = fetchAnswer(method, url, init);
  return background ? answer : whileWorking("request", answer);
}

async function fetchAnswer(method, url, { csrf = true, ...init } = {}) {
  // the session is asked about once before any other call: a page opened logged out goes to the login after that
  // one 401, not after a burst of its calls all refused
  if (needsSession(url)) await getMe();
  const headers = { Accept: "application/json", ...(init.headers || {}) };
  if (csrf && UNSAFE.has(method)) Object.assign(headers, await writeHeaders());
  let response;
  try {
    response = await fetch(url, { ...init, method, headers, credentials: "same-origin" });
  } catch (err) {
    throw new ApiError(0, `network error: ${err.message} (${method} ${url})`, null);
  }
  const text = await response.text();
  let data = null;
  if (text) {
    try {
      data = JSON.parse(text);
    } catch {
      data = text;
    }
  }
  if (response.status === 401 && url !== "/api/auth/login") toLogin();
  if (!response.ok) {
    throw new ApiError(response.status, describeError(response.status, data, response.statusText || "request failed"), data);
  }
  return { body: data, etag: response.headers.get("ETag"), entry: Number(response.headers.get("X-V3D-Audit-Entry")) || null };
}

/** fetchJson answering the parsed body only (uploads and other pages' requests). */
export async function send(method, url, options = {}) {
  return (await fetchJson(method, url, options)).body;
}

/** A JSON request; {body, etag}. `ifMatch`: the ETag of the version the write was made against. */
async function exchange(method, url, body, ifMatch, options = {}) {
  const headers = {};
  if (ifMatch) headers["If-Match"] = ifMatch;
  if (body !== undefined) headers["Content-Type"] = "application/json";
  return fetchJson(method, url, {
    ...options, headers, ...(body !== undefined ? { body: JSON.stringify(body) } : {}),
  });
}

/** A decision: always conditional on the version its page showed, so that it never overrides a decision made
 * meanwhile that its page did not show (a decision without the ETag is not sent). */
function decision(url, body, ifMatch) {
  if (!ifMatch) return Promise.reject(new Error("this page has no version of the system to decide on: reload it"));
  return exchange("POST", url, body, ifMatch);
}

function request(method, url, body, options = {}) {
  return exchange(method, url, body, undefined, options).then((answer) => answer.body);
}

/** POST /api/auth/login {name, password}: starts the browser session; answers {name, role, csrf_token}. */
export function login(name, password) {
  mePromise = null;
  return request("POST", "/api/auth/login", { name, password }, { csrf: false });
}

/** POST /api/auth/logout: ends the session (every browser session of this user). */
export async function logout() {
  leaving = true;
  await request("POST", "/api/auth/logout");
  mePromise = null;
}

/** GET /api/auth/demo: {account: {name, password} | null}, for the login page's hint. */
export function getDemoAccount() {
  return request("GET", "/api/auth/demo");
}

/** "The latest asked wins": returns `ask`, each call of which gives a check that stays true only until `ask` is
 * called again. Two requests sent in quick succession (a filter changed twice, two diffs asked) may be answered in
 * either order; a page shows an answer only while its request is still the latest asked, so that what it shows is
 * what its form now says. */
export function latestWins() {
  let asked = 0;
  return () => {
    const ticket = ++asked;
    return () => ticket === asked;
  };
}

/** Query string from an object, leaving out empty values. */
export function toQuery(params) {
  const q = new URLSearchParams();
  for (const [key, value] of Object.entries(params)) {
    if (value === undefined || value === null || value === "") continue;
    q.set(key, String(value));
  }
  const s = q.toString();
  return s ? `?${s}` : "";
}

/** GET /api/systems: one page of the review queue, with `total` and the status `counts`. */
export function listSystems(params) {
  return request("GET", `/api/systems${toQuery(params)}`);
}

/** GET /api/jobs: background jobs (imports, recomputes, exports), newest first, with their progress. `options`:
 * fetchJson's (`background` for a poll). */
export function listJobs(params = {}, options = {}) {
  return request("GET", `/api/jobs${toQuery(params)}`, undefined, options);
}

/** GET /api/games: the games, for the game filter. */
export function listGames() {
  return request("GET", "/api/games");
}

/** GET /api/systems/{id}: the system view (docs/api.md). `params` are the queue filters,
 * so that prev_id / next_id follow the queue the reviewer came from. */
export function getSystem(id, params = {}, options = {}) {
  return request("GET", `/api/systems/${encodeURIComponent(id)}${toQuery(params)}`, undefined, options);
}

/** POST /api/systems/{id}/review {status, comment}, If-Match: the system view's etag; {body: the decision, etag}. */
export function postReview(id, status, comment, ifMatch, assignee = null) {
  const body = assignee ? { status, comment, assignee } : { status, comment };
  return decision(`/api/systems/${encodeURIComponent(id)}/review`, body, ifMatch);
}

/** POST /api/frames/{id}/review {status, comment}, If-Match: the view's etag: the decision on one view (its
 * ball); {body: the view's decision, etag}. */
export function postViewReview(frameId, status, comment, ifMatch) {
  return decision(`/api/frames/${encodeURIComponent(frameId)}/review`, { status, comment }, ifMatch);
}

/** POST /api/frames/{id}/calibration-review {status, comment}, If-Match: the view's etag: the decision on the
 * view's calibration; {body: the view's decision (its `calibration` holds this one), etag}. */
export function postCalibrationReview(frameId, status, comment, ifMatch) {
  return decision(`/api/frames/${encodeURIComponent(frameId)}/calibration-review`, { status, comment }, ifMatch);
}

/** PATCH /api/frames/{id}/ball with {box} or {point}, If-Match: the view's etag; {body: the recomputed
 * system view (prev_id / next_id follow the queue given by `params`, as for getSystem), etag}. */
export function patchBall(frameId, change, params = {}, ifMatch) {
  return exchange("PATCH", `/api/frames/${encodeURIComponent(frameId)}/ball${toQuery(params)}`, change, ifMatch);
}

/** PUT /api/frames/{id}/field-lines {lines, undo_of?}, If-Match: the view's etag: replace the frame's
 * field lines ({class: [[[x, y], ...], ...]}, image px), recalibrate it; {body: the recomputed system
 * view, etag, entry: the write's audit entry}. `undoOf`: the audit entry this write undoes (its lines
 * before must be `lines`). */
export function putFieldLines(frameId, lines, params = {}, ifMatch, undoOf = null) {
  const body = undoOf ? { lines, undo_of: undoOf } : { lines };
  return exchange("PUT", `/api/frames/${encodeURIComponent(frameId)}/field-lines${toQuery(params)}`, body, ifMatch);
}

/** POST /api/frames/{id}/calibration-preview {lines}: the calibration these lines would give the view, computed as
 * the edit computes it and stored nowhere: {status, camera, jac, admitted, reason, flags, residuals_px, retry,
 * differs, pitch_lines: [{class, points}], elapsed_ms}. */
export function previewCalibration(frameId, lines) {
  return request("POST", `/api/frames/${encodeURIComponent(frameId)}/calibration-preview`, { lines });
}

let pitchModel = null;
/** GET /api/pitch-model, once per page: {classes: [{name, mirror, modelled}], length_m, width_m}. */
/** The pitch projected by a view's camera, from the view's `pitch_lines_url` (its address names the camera, so
 * one answer serves as long as that address is named): a promise of [{class, points}], asked once per address. */
const pitchLines = new Map();
export function getPitchLines(url) {
  if (!pitchLines.has(url)) {
    if (pitchLines.size > 512) pitchLines.clear();
    pitchLines.set(url, request("GET", url).then((answer) => answer.lines, (err) => {
      pitchLines.delete(url);
      throw err;
    }));
  }
  return pitchLines.get(url);
}

export function getPitchModel() {
  if (!pitchModel) {
    pitchModel = request("GET", "/api/pitch-model").catch((err) => {
      pitchModel = null;
      throw err;
    });
  }
  return pitchModel;
}

/** POST /api/frames/{id}/field-lines/mirror: replace the frame's field lines by their mirrored
 * labelling (the fix of a view flagged probably_mirrored); {body: the recomputed system view, etag}. */
export function mirrorFieldLines(frameId, params = {}, ifMatch) {
  return exchange("POST", `/api/frames/${encodeURIComponent(frameId)}/field-lines/mirror${toQuery(params)}`, undefined, ifMatch);
}

/** POST /api/frames/{id}/exclusion {excluded}: exclude the view from its system's triangulation (true)
 * or restore it (false); {body: the recomputed system view, etag}. */
export function postExclusion(frameId, excluded, params = {}, ifMatch) {
  return exchange("POST", `/api/frames/${encodeURIComponent(frameId)}/exclusion${toQuery(params)}`, { excluded }, ifMatch);
}

/** GET /api/audit: a page of the audit log, newest first ({items, total, limit, offset}). */
export function listAudit(params) {
  return request("GET", `/api/audit${toQuery(params)}`);
}

/** POST /api/audit/{id}/revert (reviewers): {body: the recomputed system view, etag}. 409 when the
 * resource changed since the entry, unless `force`. */
export function revertEntry(id, params = {}, force = false) {
  return exchange("POST", `/api/audit/${encodeURIComponent(id)}/revert${toQuery({ ...params, force: force || undefined })}`);
}

/** POST /api/audit/{id}/undo: undo the entry (the page's Ctrl+Z; the redo is the undo of the undo's entry):
 * {body: the recomputed system view, etag: the resource's new one, entry: the undo's own audit entry}. 409
 * when the resource changed since the entry; 403 for an annotator undoing another's edit or a system decision. */
export function undoEntry(id, params = {}) {
  return exchange("POST", `/api/audit/${encodeURIComponent(id)}/undo${toQuery(params)}`);
}

/** GET /api/games/{id}/trajectory: an ISSIA sequence's ball over time (observed and fitted, per frame). */
export function getTrajectory(gameId) {
  return request("GET", `/api/games/${encodeURIComponent(gameId)}/trajectory`);
}

/** POST /api/passes {filter, sort, system_id}: begin (or continue) the caller's review pass over a queue;
 * answers the pass {id, systems (frozen ids, every page), position, counts, ...}. */
export function startPass(filter, sort, systemId, fresh = false) {
  return request("POST", "/api/passes", { filter, sort, system_id: systemId, fresh });
}

/** POST /api/passes/{id}/visits {system_id}: the owner opened that system (the pass resumes there);
 * answers its place {index, total, prev_id, next_id, next_pending_id, first_pending_id, counts, finished}. */
export function visitPass(passId, systemId) {
  return request("POST", `/api/passes/${encodeURIComponent(passId)}/visits`, { system_id: systemId });
}

/** GET /api/passes/{id}/place?system_id=: where a system stands in a pass, statuses read now. */
export function passPlace(passId, systemId) {
  return request("GET", `/api/passes/${encodeURIComponent(passId)}/place${toQuery({ system_id: systemId })}`);
}

/** GET /api/passes: the caller's newest passes (without their system lists), to resume one. */
export function listPasses(params = {}) {
  return request("GET", `/api/passes${toQuery(params)}`);
}

/** GET /api/passes/{id}: a review pass with its frozen `systems` and counts. */
export function getPass(passId) {
  return request("GET", `/api/passes/${encodeURIComponent(passId)}`);
}

/** POST /api/batches {filter, confidence, max_wrong_share}: a batch of the queue's pending vouched systems with the
 * server's random sample; answers {id, systems, sample, plan, state, stops, ...}. Reviewers. */
export function createBatch(filter, confidence = 0.95, maxWrongShare = 0.05) {
  return request("POST", "/api/batches", { filter, confidence, max_wrong_share: maxWrongShare });
}

/** GET /api/batches/{id}: a batch and, while open, what stops its accept now (`stops`: [{system_id, words, final}]). */
export function getBatch(batchId) {
  return request("GET", `/api/batches/${encodeURIComponent(batchId)}`);
}

/** POST /api/batches/{id}/accept: accept the batch's unsampled systems; answers {accepted} (409 naming what stops it). */
export function acceptBatch(batchId) {
  return request("POST", `/api/batches/${encodeURIComponent(batchId)}/accept`);
}

/** POST /api/batches/{id}/pass: the caller's review pass over the batch's sample (the pass, as POST /api/passes). */
export function batchPass(batchId) {
  return request("POST", `/api/batches/${encodeURIComponent(batchId)}/pass`);
}
