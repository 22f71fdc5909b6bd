// Who is logged in, in the page header: "name · role" and a "Log out" button, after the sections' links every
// page shares (topbar.js). Imported by every page module; a page opened without a session is sent to the login
// page by api.js (on the first 401).
import { getMe, logout, LOGIN_PAGE } from "./api.js";
import { el } from "./format.js";
import { mountAdminLinks, mountTopbar } from "./topbar.js";

async function showUser() {
  const bar = document.querySelector(".topbar");
  if (!bar) return;
  let me;
  try {
    me = await getMe();
  } catch {
    return; // 401: api.js is taking the person to the login page; other errors show on the page's own calls
  }
  mountAdminLinks(me);
  const button = el("button", { type: "button", "data-testid": "logout", title: "End this session (every browser session of this user)" }, "Log out");
  button.addEventListener("click", async () => {
    button.disabled = true;
    try {
      await logout();
    } catch {
      // the session may already be over: the login page is the right place either way
    }
    location.assign(LOGIN_PAGE);
  });
  bar.append(el("span", { class: "user", "data-testid": "user", title: `logged in as ${me.role} (${me.via})` },
    el("b", { "data-testid": "user-name" }, me.name), el("span", { class: "user-role" }, ` · ${me.role}`)), button);
}

mountTopbar();
showUser();
