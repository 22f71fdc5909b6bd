// The review queue's filters and order, as kept in the address bar (`?status=pending&jac_max=80...`)
// and as sent to the API. Shared by the queue page and the system page, so that a system opened from
// a filtered queue moves (prev / next, after a decision) within that same queue.

export const FILTERS = ["status", "game", "jac_min", "jac_max", "error_min", "error_max", "sigma_min", "sigma_max",
  "doubt", "camera", "ball_evidence", "assignee", "sort"];
/** The API's default order: the work to do first (pending, fixed), the most severe doubt first. */
export const DEFAULT_SORT = "-severity";

/** Queue state from a query string; JaC bounds are in percent, as the reviewer types them. */
export function readState(search = location.search) {
  const q = new URLSearchParams(search);
  const state = {};
  for (const key of FILTERS) state[key] = q.get(key) || "";
  if (!state.sort) state.sort = DEFAULT_SORT;
  state.page = Math.max(0, parseInt(q.get("page") || "0", 10) || 0);
  // the page's place by cursor (the API's next_cursor / prev_cursor); `page` then only numbers it
  // rows per page (a link may ask for another size; the API takes 1-500)
  const limit = parseInt(q.get("limit") || "", 10);
  state.limit = limit >= 1 && limit <= 500 ? limit : "";
  state.after = q.get("after") || "";
  state.before = q.get("before") || "";
  return state;
}

/** The query string of a state ("" when everything is default). */
export function stateQuery(state, { withPage = true } = {}) {
  const q = new URLSearchParams();
  for (const key of FILTERS) {
    if (state[key] && !(key === "sort" && state[key] === DEFAULT_SORT)) q.set(key, state[key]);
  }
  if (withPage && state.limit) q.set("limit", String(state.limit));
  if (withPage && state.page) q.set("page", String(state.page));
  if (withPage && state.after) q.set("after", state.after);
  else if (withPage && state.before) q.set("before", state.before);
  const s = q.toString();
  return s ? `?${s}` : "";
}

/** Query parameters of the API's queue (GET /api/systems, and prev / next of GET /api/systems/{id}):
 * the API takes JaC as a fraction and the game as `game_id`. */
export function apiFilters(state) {
  const frac = (v) => (v === "" || v === undefined ? "" : String(Number(v) / 100));
  return {
    status: state.status,
    game_id: state.game,
    jac_min: frac(state.jac_min),
    jac_max: frac(state.jac_max),
    error_min: state.error_min,
    error_max: state.error_max,
    sigma_min: state.sigma_min, // the 3D ball's sigma, metres
    sigma_max: state.sigma_max,
    doubt: state.doubt,
    camera: state.camera, // a calibration source flag (placed by players, at a rig position)
    ball_evidence: state.ball_evidence, // what backs the 3D ball: vouched, unconfirmed, doubted, none
    assignee: state.assignee, // a user's name, "me" or "none" (work assignment)
    sort: state.sort,
  };
}
