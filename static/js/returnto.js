// Whom a "needs fix" goes to when the server finds no one (nobody edited the system's labels and nobody is assigned
// to it: the decision is refused, 422 naming `assignee`). The review card then offers the team's annotators (every
// enabled user when there is no annotator) and the reviewer chooses; the decision is sent again with that name.
// Nothing is ever returned to nobody.

import { send } from "./api.js";
import { el } from "./format.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);

/** Whether `err` is the server's refusal of a needs fix that found no one to return the system to. */
export function needsAChosenPerson(err) {
  return err?.status === 422 && err.body?.field === "assignee";
}

/** The people a needs fix may go to: the team's annotators, or, with none, every enabled user ({name, role}). */
async function candidates() {
  const users = await send("GET", "/api/assignees");
  const annotators = users.filter((u) => u.role === "annotator");
  return annotators.length ? annotators : users;
}

/** Ask in the review card whom the system goes to, with the server's reason (`why`); answers the chosen name, or
 * null when the reviewer cancels (Esc or the Cancel button: the system keeps its decision). */
export async function askWhomToReturn(why) {
  $("return-to")?.remove();
  const people = await candidates();
  return new Promise((resolve) => {
    const choice = el("select", { "data-testid": "return-to-user", "aria-label": "return the system to" },
      people.map((u) => el("option", { value: u.name }, `${u.name} (${u.role})`)));
    const sendIt = el("button", { type: "button", "data-testid": "return-to-send" }, "Return to them");
    const cancel = el("button", { type: "button", "data-testid": "return-to-cancel" }, "Cancel");
    const box = el("div", { class: "return-to", role: "group", "aria-label": "whom the needs fix goes to",
      "data-testid": "return-to" },
    el("p", { "data-testid": "return-to-why" }, `Needs fix: ${why}.`),
    el("label", {}, "Return it to ", choice), sendIt, cancel);
    const done = (name) => {
      box.remove();
      resolve(name);
    };
    sendIt.addEventListener("click", () => done(choice.value || null));
    cancel.addEventListener("click", () => done(null));
    box.addEventListener("keydown", (e) => {
      e.stopPropagation(); // the page's keys stay out of the chooser
      if (e.key === "Escape") done(null);
      if (e.key === "Enter" && e.target === choice) done(choice.value || null);
    });
    $("review-card").append(box);
    if (!people.length) {
      sendIt.disabled = true;
      box.append(el("p", {}, "There is no enabled user to return it to: add an annotator first."));
    }
    box.scrollIntoView({ block: "nearest" });
    choice.focus();
  });
}
