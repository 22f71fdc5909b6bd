// A ball label made from a doubt's suggestion: it keeps its provenance and makes no 3D ball until a
// person places it. The view's zoom inset shows the image crop around it; this note says where the label came
// from and offers "Confirm placement", which sends the same box as a person's label (an edit without
// provenance). Dragging or resizing the box places it as well.

import { el } from "./format.js";
import { chip, word } from "./words.js";

/**
 * The facts-panel rows (a <dt> and a <dd>) of a suggested label, or [] for a label a person placed.
 * @param {object} ball the view's `ball` (BallOut): `provenance` {doubt, code, from_views} while suggested.
 * @param {object} names frame id -> image name of the system's views.
 * @param {() => void} onConfirm sends the label as placed by a person.
 */
export function suggestedNote(ball, names, onConfirm) {
  const p = ball && ball.provenance;
  if (!p || !ball.kind) return [];
  const from = (p.from_views || []).map((id) => names[id] || `frame ${id}`).join(", ");
  const rule = p.doubt && p.code ? word("placement", `${p.doubt}:${p.code}`) : null; // which rule placed it
  const by = p.detector ? ` (${p.detector}${p.score != null ? `, score ${p.score}` : ""})` : "";
  return [
    el("dt", { class: "bad" }, "Suggested"),
    el("dd", { class: "suggested", "data-testid": "view-suggested" },
      `placed from ${from || "the other views"} by a ${p.doubt ? chip("doubt", p.doubt) : "doubt"} fix${by}${rule && rule.means ? `: ${rule.means}` : ""}. It makes no 3D ball until you check it on the close-up and confirm or move it. `,
      el("button", { type: "button", "data-testid": "confirm-suggested", onclick: onConfirm }, "Confirm placement")),
  ];
}
