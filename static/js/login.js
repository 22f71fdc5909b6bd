// Login page: POST /api/auth/login, then back to the page the person came from (?next=, same origin
// only). Shows the demo account's name and password when `v3d serve --demo` made one (GET /api/auth/demo).
import { ApiError, login, getDemoAccount } from "./api.js";
import { el } from "./format.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);
const form = $("login-form");

/** The page to return to: a path of this site (never another origin, never the login page itself).
 * `next` is resolved as the browser resolves it when it navigates (dropping tabs and newlines, reading `\`
 * as `/`: `/%09/evil.example` and `/\\evil.example` both mean `//evil.example`) and kept only when it stays
 * on this origin; the answer is rebuilt from the resolved path, query and fragment. */
export function nextPage(search = location.search, origin = location.origin) {
  const next = new URLSearchParams(search).get("next") || "/";
  let url;
  try {
    url = new URL(next, origin);
  } catch {
    return "/";
  }
  if (!next.startsWith("/") || url.origin !== origin || url.pathname.startsWith("/login")) return "/";
  // A path that resolved to `//host` (from `/..//host`) would be read as another origin: one leading slash.
  return url.pathname.replace(/^\/+/, "/") + url.search + url.hash;
}

/** Why the person is here, when a page sent them: its session ended (`ended=1`), the page they return to, and
 * whether what they had typed there is kept (`kept=1`, drafts.js). */
function showEnded(search = location.search) {
  const params = new URLSearchParams(search);
  if (params.get("ended") !== "1") return;
  const box = $("login-ended");
  const where = el("span", { class: "mono" }, nextPage(search));
  box.replaceChildren(el("b", {}, "Your session ended"),
    " (it expired, or this account logged out elsewhere). Log in again to go back to ", where,
    params.get("kept") === "1" ? "; the text you had typed there is kept and put back." : ".");
  box.hidden = false;
}

function showError(message) {
  const box = $("login-error");
  box.textContent = message;
  box.hidden = false;
}

form.addEventListener("submit", async (event) => {
  event.preventDefault();
  $("login-error").hidden = true;
  const button = $("login-submit");
  button.disabled = true;
  const data = new FormData(form);
  try {
    await login(String(data.get("name")), String(data.get("password")));
    location.assign(nextPage());
  } catch (err) {
    showError(err instanceof ApiError && err.status === 401 ? "Wrong name or password." : String(err.message || err));
    button.disabled = false;
  }
});
// The page's button is disabled until now: a person (or a test) quicker than this module would have sent the
// form natively, a GET to /login with the password in the address (seen in CI: a login that never left).
$("login-submit").disabled = false;

async function showDemoHint() {
  let answer;
  try {
    answer = await getDemoAccount();
  } catch {
    return;
  }
  if (!answer || !answer.account) return;
  const { name, password } = answer.account;
  $("demo-name").textContent = name;
  $("demo-password").textContent = password;
  $("demo-fill").addEventListener("click", () => {
    form.elements.name.value = name;
    form.elements.password.value = password;
    $("login-submit").focus();
  });
  $("demo-hint").hidden = false;
}

showEnded();
showDemoHint();
