// Users page (static/users.html, admins): the users (GET /api/users) with their role (changed in place: PATCH
// /api/users/{name}), their state and how many API tokens work; a new user (POST /api/users), disabling and enabling
// one (after a confirmation in words: disabling revokes every token for good); one user's API tokens (GET .../tokens),
// another issued (POST .../tokens) and one revoked (DELETE .../tokens/{id}). A token is shown once, when it is made:
// only its fingerprint is stored. Every text from the server is set as text, never as markup.
import { getMe, send } from "./api.js";
import "./session.js";
import { el, fmtWhen, showError, clearError } from "./format.js";

const $ = (id) => document.querySelector(`[data-testid=${id}]`);
const JSON_HEADERS = { "Content-Type": "application/json" };
const plural = (n, word) => `${n} ${word}${n === 1 ? "" : "s"}`;

/** The user whose tokens the tokens panel shows (null: none chosen yet). */
let tokensOf = null;
/** The roles a user may have, the least trusted first: the admin's own `roles` (app.api.auth.ROLES). */
let roles = [];

function userPath(name) {
  return `/api/users/${encodeURIComponent(name)}`;
}

function when(iso) {
  if (!iso) return el("span", { class: "muted" }, "—");
  const { text, title } = fmtWhen(iso);
  return el("time", { datetime: iso, title }, text);
}

/** Show a token just made, once, with whose it is. */
function showToken(words, token) {
  $("token-shown-text").textContent = `${words}: copy it now, it is shown this once.`;
  $("token-value").textContent = token;
  $("token-shown").hidden = false;
}

async function changeRole(user, select) {
  try {
    await send("PATCH", userPath(user.name), { headers: JSON_HEADERS, body: JSON.stringify({ role: select.value }) });
    clearError();
    await loadUsers();
  } catch (e) {
    select.value = user.role;
    showError(`${user.name}: ${e.message}`);
  }
}

async function setDisabled(user, disabled) {
  if (disabled && !window.confirm(`Disable ${user.name}? Their sessions end now and their ${plural(user.tokens, "working API token")} `
    + `${user.tokens === 1 ? "is" : "are"} revoked for good (enabling them again brings no token back).`)) return;
  try {
    await send("PATCH", userPath(user.name), { headers: JSON_HEADERS, body: JSON.stringify({ disabled }) });
    clearError();
    await loadUsers();
    if (tokensOf === user.name) await loadTokens(user.name);
  } catch (e) {
    showError(`${user.name}: ${e.message}`);
  }
}

/** The admin looking at the page: their own account is not offered a Disable (it would end this very session). */
let myName = null;

function userRow(user) {
  const role = el("select", { "data-testid": "user-role", "aria-label": `role of ${user.name}` },
    roles.map((r) => el("option", { value: r, selected: r === user.role }, r)));
  role.addEventListener("change", () => changeRole(user, role));
  const toggle = user.disabled
    ? el("button", { type: "button", "data-testid": "user-enable" }, "Enable")
    : el("button", { type: "button", "data-testid": "user-disable" }, "Disable");
  toggle.addEventListener("click", () => setDisabled(user, !user.disabled));
  if (user.name === myName) toggle.hidden = true;
  const tokens = el("button", { type: "button", "data-testid": "user-tokens", "aria-controls": "tokens-panel" },
    "API tokens");
  tokens.addEventListener("click", () => loadTokens(user.name).catch((e) => showError(e.message)));
  return el("tr", { "data-testid": "user-row", "data-name": user.name, class: user.disabled ? "disabled" : null },
    el("td", { "data-testid": "user-cell-name" }, user.name, user.demo ? el("span", { class: "muted" }, " (demo)") : null),
    el("td", {}, role),
    el("td", {}, when(user.created_at)),
    el("td", { class: "num", "data-testid": "user-token-count" }, String(user.tokens)),
    el("td", { "data-testid": "user-state" }, user.disabled ? "disabled" : "active"),
    el("td", { class: "actions" }, toggle, tokens));
}

async function loadUsers() {
  const users = await send("GET", "/api/users");
  $("users").querySelector("tbody").replaceChildren(...users.map(userRow));
}

async function revoke(name, token) {
  const what = token.label ? `token ${token.id} (${token.label})` : `token ${token.id}`;
  if (!window.confirm(`Revoke ${name}'s ${what}? It stops working at once, for good.`)) return;
  try {
    await send("DELETE", `${userPath(name)}/tokens/${token.id}`);
    clearError();
    await Promise.all([loadTokens(name), loadUsers()]);
  } catch (e) {
    showError(`${name}: ${e.message}`);
  }
}

function tokenRow(name, token) {
  const cells = [
    el("td", { class: "num", "data-testid": "token-id" }, String(token.id)),
    el("td", { "data-testid": "token-label" }, token.label ?? el("span", { class: "muted" }, "—")),
    el("td", {}, when(token.created_at)),
    el("td", {}, token.last_used_at ? when(token.last_used_at) : el("span", { class: "muted" }, "never")),
    el("td", {}, token.expires_at ? when(token.expires_at) : el("span", { class: "muted" }, "never")),
    el("td", { "data-testid": "token-state" }, token.state),
  ];
  const actions = el("td", { class: "actions" });
  if (token.state === "active") {
    const button = el("button", { type: "button", "data-testid": "token-revoke" }, "Revoke");
    button.addEventListener("click", () => revoke(name, token));
    actions.append(button);
  }
  return el("tr", { "data-testid": "token-row", "data-id": token.id }, ...cells, actions);
}

async function loadTokens(name) {
  const tokens = await send("GET", `${userPath(name)}/tokens`);
  tokensOf = name;
  $("tokens-heading").textContent = `API tokens of ${name}`;
  $("tokens").querySelector("tbody").replaceChildren(...tokens.map((t) => tokenRow(name, t)));
  $("tokens-panel").hidden = false;
}

function mountForms() {
  const form = $("user-form");
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const body = { name: form.elements.name.value.trim(), role: form.elements.role.value,
      password: form.elements.password.value };
    try {
      const made = await send("POST", "/api/users", { headers: JSON_HEADERS, body: JSON.stringify(body) });
      clearError();
      form.reset();
      showToken(`${made.name} added as ${body.role}; their first API token`, made.token);
      await Promise.all([loadUsers(), loadTokens(made.name)]);
    } catch (e) {
      showError(`new user ${body.name}: ${e.message}`);
    }
  });
  const tokenForm = $("token-form");
  tokenForm.addEventListener("submit", async (event) => {
    event.preventDefault();
    if (!tokensOf) return;
    const name = tokensOf;
    const days = tokenForm.elements.expires_days.value;
    const body = { label: tokenForm.elements.label.value.trim() || null, expires_days: days ? Number(days) : null };
    try {
      const issued = await send("POST", `${userPath(name)}/tokens`, { headers: JSON_HEADERS, body: JSON.stringify(body) });
      clearError();
      tokenForm.reset();
      showToken(`New API token of ${name}${issued.label ? ` (${issued.label})` : ""}`, issued.token);
      await Promise.all([loadTokens(name), loadUsers()]);
    } catch (e) {
      showError(`${name}: ${e.message}`);
    }
  });
  $("token-shown-close").addEventListener("click", () => {
    $("token-value").textContent = "";
    $("token-shown").hidden = true;
  });
}

async function load() {
  $("error-dismiss").addEventListener("click", clearError);
  const me = await getMe();
  if (me.role !== "admin") {
    $("users-admins-only").hidden = false;
    return;
  }
  roles = me.roles;
  myName = me.name;
  $("user-role-input").replaceChildren(...roles.map((r) => el("option", { value: r }, r)));
  mountForms();
  await loadUsers();
  $("users-panel").hidden = false;
}

load().catch((e) => showError(e.message));
