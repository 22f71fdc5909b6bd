// REST client: every request the pages make goes through here, so the contract lives in one file.

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

async function request(method, url, body) {
  const init = { method, headers: { Accept: "application/json" } };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  let response;
  try {
    response = await fetch(url, init);
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
  if (!response.ok) {
    throw new ApiError(response.status, describeError(response.status, data, response.statusText || "request failed"), data);
  }
  return data;
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

/** GET /api/games: the games, for the game filter. */
export function listGames() {
  return request("GET", "/api/games");
}

/** GET /api/systems/{id}: the system view (docs/architecture.md). `params` are the queue filters,
 * so that prev_id / next_id follow the queue the reviewer came from. */
export function getSystem(id, params = {}) {
  return request("GET", `/api/systems/${encodeURIComponent(id)}${toQuery(params)}`);
}

/** POST /api/systems/{id}/review {status, comment}. */
export function postReview(id, status, comment) {
  return request("POST", `/api/systems/${encodeURIComponent(id)}/review`, { status, comment });
}

/** PATCH /api/frames/{id}/ball with {box} or {point}; answers the recomputed system view, whose
 * prev_id / next_id follow the queue given by `params` (as for getSystem). */
export function patchBall(frameId, change, params = {}) {
  return request("PATCH", `/api/frames/${encodeURIComponent(frameId)}/ball${toQuery(params)}`, change);
}

/** POST /api/frames/{id}/field-lines/mirror: replace the frame's field lines by their mirrored
 * labelling (the fix of a view flagged probably_mirrored); answers the recomputed system view. */
export function mirrorFieldLines(frameId, params = {}) {
  return request("POST", `/api/frames/${encodeURIComponent(frameId)}/field-lines/mirror${toQuery(params)}`);
}

/** POST /api/frames/{id}/exclusion {excluded}: exclude the view from its system's triangulation (true)
 * or restore it (false); answers the recomputed system view. */
export function postExclusion(frameId, excluded, params = {}) {
  return request("POST", `/api/frames/${encodeURIComponent(frameId)}/exclusion${toQuery(params)}`, { excluded });
}

/** GET /api/games/{id}/trajectory: an ISSIA sequence's ball over time (observed and fitted, per frame). */
export function getTrajectory(gameId) {
  return request("GET", `/api/games/${encodeURIComponent(gameId)}/trajectory`);
}
