// Number formatting and the colour rules shared by the queue and the system page.

export const STATUSES = ["pending", "accepted", "rejected", "needs_fix", "fixed"];
export const STATUS_LABEL = { pending: "pending", accepted: "accepted", rejected: "rejected", needs_fix: "needs fix", fixed: "fixed, to re-review" };

import { LABEL_KINDS, WORDS } from "./words.js";

/** Short names of the doubt kinds that accuse a label, in the contract's order: kinds and words both from
 * words.js (written from app/geometry/doubts/contract.py and app/services/wording/words.py). */
export const DOUBT_LABEL = Object.fromEntries(LABEL_KINDS.map((k) => [k, WORDS.doubt[k].chip]));

export const isNum = (v) => typeof v === "number" && Number.isFinite(v);

export function fmt(v, digits = 1, unit = "") {
  return isNum(v) ? `${v.toFixed(digits)}${unit}` : "—";
}

/** JaC in [0, 1] shown as a percentage. */
export function fmtJac(v) {
  return isNum(v) ? `${(100 * v).toFixed(1)}%` : "—";
}

/** "error_above_tau" -> "error above tau" (machine codes shown to people). */
export function human(code) {
  return typeof code === "string" ? code.replaceAll("_", " ") : code;
}

export function fmtXYZ(p, digits = 2) {
  return Array.isArray(p) && p.every(isNum) ? p.map((c) => c.toFixed(digits)).join(", ") : "—";
}

/** "ok" below tau / 2, "warn" up to tau, "bad" above: the reviewer's traffic light, on the error the
 * server scaled by the pair rule (the view's `reprojection_error_scaled_px`; never rescaled here). */
export function errorClass(scaledErrorPx, tau) {
  if (!isNum(scaledErrorPx) || !isNum(tau)) return "muted";
  if (scaledErrorPx <= tau / 2) return "ok";
  if (scaledErrorPx <= tau) return "warn";
  return "bad";
}

export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === null || v === false) continue;
    if (k === "class") node.className = v;
    else if (k === "text") node.textContent = v;
    else if (k === "dataset") Object.assign(node.dataset, v);
    else if (k.startsWith("on") && typeof v === "function") node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v === true ? "" : String(v));
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    node.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return node;
}

const SVG_NS = "http://www.w3.org/2000/svg";
export function svg(tag, attrs = {}, ...children) {
  const node = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === null || v === false) continue;
    if (k === "class") node.setAttribute("class", v);
    else if (k === "text") node.textContent = v;
    else if (k === "dataset") Object.assign(node.dataset, v);
    else node.setAttribute(k, String(v));
  }
  for (const c of children.flat()) if (c) node.append(c);
  return node;
}

/** The pointer of `event` in image px of the view's SVG `root`: through `inverse` (the SVG's screen matrix inverted,
 * kept from a drag's press so that the page moving under a drag does not move what is dragged), or through the
 * SVG's matrix now; null when the SVG is not rendered. */
export function pointerImagePx(root, event, inverse = root.getScreenCTM()?.inverse()) {
  if (!inverse) return null;
  const p = new DOMPoint(event.clientX, event.clientY).matrixTransform(inverse);
  return [p.x, p.y];
}

/** True when a key event comes from a place where the reviewer types text. */
export function isTyping(event) {
  const t = event.target;
  if (!(t instanceof HTMLElement)) return false;
  return t.isContentEditable || ["INPUT", "TEXTAREA", "SELECT"].includes(t.tagName);
}

/** Colour tag of view i (same colour on the view card and on the pitch map). */
const VIEW_COLOURS = ["#4da3ff", "#ffb347", "#7ee787", "#ff7ab6", "#c297ff", "#5ce0d8", "#f2cc60", "#ff8f70"];
export function viewColour(i) {
  return VIEW_COLOURS[i % VIEW_COLOURS.length];
}

/** Error bar of a page: shows API errors until dismissed. */
export function showError(message) {
  const bar = document.querySelector("[data-testid=error]");
  if (!bar) return;
  bar.querySelector(".msg").textContent = message;
  bar.classList.add("visible");
}
export function clearError() {
  const bar = document.querySelector("[data-testid=error]");
  if (bar) bar.classList.remove("visible");
}

let toastTimer = null;
/** A short message at the bottom of the page (`data-testid="toast"`) for 2.5 s: what a key or an edit did, or why
 * a key cannot act. */
export function toast(message) {
  const t = document.querySelector('[data-testid="toast"]');
  if (!t) return;
  t.textContent = message;
  t.classList.add("visible");
  clearTimeout(toastTimer);
  toastTimer = setTimeout(() => t.classList.remove("visible"), 2500);
}

/** A byte count in a reader's unit: "812 B", "50 KB", "3.4 MB", "1.2 GB" (1024-based, as file managers show). */
export function fmtBytes(bytes) {
  if (!isNum(bytes) || bytes < 0) return "—";
  if (bytes < 1024) return `${bytes} B`;
  const units = ["KB", "MB", "GB", "TB"];
  let v = bytes / 1024;
  let i = 0;
  while (v >= 1024 && i < units.length - 1) {
    v /= 1024;
    i += 1;
  }
  return `${v < 10 ? v.toFixed(1).replace(/\.0$/, "") : Math.round(v)} ${units[i]}`;
}

/** A whole number with the reader's thousands separator ("1,420"). */
export function fmtCount(n) {
  return isNum(n) ? Math.round(n).toLocaleString() : "—";
}

const RELATIVE_STEPS = [["year", 31536000], ["month", 2592000], ["week", 604800], ["day", 86400], ["hour", 3600], ["minute", 60]];
/** A moment (ISO 8601 text, or a Date) in the reader's words: `{text, title}`, the text relative to now ("3 minutes
 * ago", "yesterday") and the title the full date and time in the reader's locale and time zone (shown on hover). */
export function fmtWhen(when, now = Date.now()) {
  const d = when instanceof Date ? when : new Date(typeof when === "string" && !/[zZ]|[+-]\d\d:?\d\d$/.test(when) ? `${when}Z` : when);
  if (Number.isNaN(d.getTime())) return { text: "unknown", title: "" };
  const title = d.toLocaleString(undefined, { dateStyle: "full", timeStyle: "long" });
  const seconds = (d.getTime() - now) / 1000;
  const rtf = new Intl.RelativeTimeFormat(undefined, { numeric: "auto" });
  for (const [unit, size] of RELATIVE_STEPS) {
    if (Math.abs(seconds) >= size) return { text: rtf.format(Math.round(seconds / size), unit), title };
  }
  return { text: Math.abs(seconds) < 10 ? "just now" : rtf.format(Math.round(seconds), "second"), title };
}
