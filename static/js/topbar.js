// The one top bar's links, the same on every page (queue, system, statistics, detectors, releases), with the same
// names in the same order: the one home of the site's sections. `session.js` (imported by every page module) puts
// them in the page's `.topbar` before its spacer, and for an admin the admins' sections after them; the page the
// reader is on is marked (aria-current), not dropped, so that no link moves from page to page. The login page has no bar of links (nothing behind it is open yet).

import { el } from "./format.js";

/** The sections: [data-testid, name, address, what it holds (the link's title)]. */
export const SECTIONS = [
  ["link-queue", "Review queue", "/", "The systems to review, with their doubts, filters and the jobs"],
  ["link-stats", "Statistics", "/static/stats.html", "The dataset at a glance, and each annotator's and reviewer's figures"],
  ["link-monocular", "Detectors", "/static/monocular.html", "The ball detectors' predictions imported, and how well a detector finds the curated balls"],
  ["link-releases", "Releases", "/static/releases.html", "Named, immutable releases of the accepted systems: make, export and compare them"],
];

/** The admins' sections, after the others for an admin only (mountAdminLinks): who may do what, and who did what. */
export const ADMIN_SECTIONS = [
  ["link-users", "Users", "/static/users.html", "The users, their roles and API tokens (admins)"],
  ["link-audit", "Audit", "/static/audit.html", "Every change, who made it and when: the whole audit log"],
];

/** Is `href` the page at `path`? ("/" is the queue, "/systems/..." a system of it, but the queue is not current there.) */
function current(href, path) {
  return href === "/" ? path === "/" || path === "/index.html" : path === href;
}

/** Put the sections' links in `bar` (before its first `.spacer`, else at its end), once. */
export function mountTopbar(bar = document.querySelector(".topbar"), where = location) {
  if (!bar || bar.querySelector("[data-testid=site-nav]")) return;
  const nav = el("nav", { class: "site-nav", "data-testid": "site-nav", "aria-label": "sections" });
  for (const [testid, name, href, title] of SECTIONS) {
    // from a system page the queue link keeps the queue's filters and order (the page's own address carries them)
    const to = href === "/" && where.pathname.startsWith("/systems/") ? `/${where.search}` : href;
    nav.append(sectionLink(testid, name, to, title, current(href, where.pathname)));
  }
  const spacer = bar.querySelector(":scope > .spacer");
  if (spacer) spacer.before(nav);
  else bar.append(nav);
}

function sectionLink(testid, name, href, title, here) {
  const a = el("a", { href, "data-testid": testid, title }, name);
  if (here) a.setAttribute("aria-current", "page");
  return a;
}

/** Add the admins' sections (ADMIN_SECTIONS) to the bar's links, once, when `me` is an admin. */
export function mountAdminLinks(me, bar = document.querySelector(".topbar"), where = location) {
  const nav = bar?.querySelector("[data-testid=site-nav]");
  if (!nav || me.role !== "admin" || nav.querySelector("[data-testid=link-users]")) return;
  for (const [testid, name, href, title] of ADMIN_SECTIONS) {
    nav.append(sectionLink(testid, name, href, title, where.pathname === href));
  }
}
