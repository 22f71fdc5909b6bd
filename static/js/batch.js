// Accept the vouched after a sample (/api/batches): the queue page's button makes a batch of the queue's pending
// systems whose ball is vouched for, with the server's random sample, and opens a review pass over the sample
// (`?pass=ID&batch=ID`); the system page counts it "sample 3 of 59". At the end of the sample the page offers
// "accept the other 181" with the plan in words; a sampled system rejected (or returned for a fix) ends the batch,
// and the page says so, naming it.

import { ApiError, acceptBatch, batchPass, createBatch, getBatch, getMe } from "./api.js";
import { el, showError, toast } from "./format.js";
import { apiFilters, readState } from "./queuestate.js";

export const BATCH_PARAM = "batch";

/** The batch id of a query string, or null. */
export function batchIdOf(search = location.search) {
  const id = Number(new URLSearchParams(search).get(BATCH_PARAM));
  return Number.isInteger(id) && id > 0 ? id : null;
}

/** The queue's filters of a query string as POST /api/batches takes them: empty ones and the sort left out, and the
 * status too when it is pending (a batch takes pending systems only; another status is the server's to refuse). */
export function batchFilter(search = location.search) {
  const { sort, ...filters } = apiFilters(readState(search));
  void sort;
  return Object.fromEntries(Object.entries(filters).filter(([k, v]) => v !== "" && v !== undefined
    && !(k === "status" && v === "pending")));
}

/** The queue page's "Accept the vouched after a sample" button with the plan's two percentages (reviewers and
 * admins; `group` holds them): make the batch, begin the pass over its sample and open its first system. */
export async function mountBatchButton(group) {
  if (!group) return;
  const me = await getMe().catch(() => null);
  if (!me || me.role === "annotator") return;
  group.hidden = false;
  const button = group.querySelector("[data-testid=batch-start]");
  const percent = (name) => Number(group.querySelector(`[data-testid=${name}]`).value) / 100;
  button.addEventListener("click", async () => {
    button.disabled = true;
    try {
      const batch = await createBatch(batchFilter(), percent("batch-confidence"), percent("batch-wrong"));
      if (!batch.sample.length) {
        toast("No pending system of this queue has a vouched 3D ball: nothing to sample.");
        return;
      }
      const rp = await batchPass(batch.id);
      const q = new URLSearchParams(location.search);
      for (const k of ["page", "after", "before", "limit"]) q.delete(k);
      q.set("pass", String(rp.id));
      q.set(BATCH_PARAM, String(batch.id));
      location.assign(`/systems/${encodeURIComponent(batch.sample[0])}?${q}`);
    } catch (err) {
      showError(`batch: ${err.message}`);
    } finally {
      button.disabled = false;
    }
  });
}

/** The end of a sample's pass on the system page: the batch read now; either what stops it (a rejection: the batch
 * ends) or the offer to accept the others with the plan in words. `panel`: where it is said; `queueUrl`: back. */
export async function showBatchEnd(panel, batchId, queueUrl) {
  let batch;
  try {
    batch = await getBatch(batchId);
  } catch (err) {
    showError(`batch ${batchId}: ${err.message}`);
    return;
  }
  const back = el("a", { href: queueUrl, class: "button", "data-testid": "pass-queue-link" }, "back to the queue (u)");
  const others = batch.systems.length - batch.sample.length;
  const final = (batch.stops || []).filter((s) => s.final);
  const waiting = (batch.stops || []).filter((s) => !s.final);
  if (batch.state === "refused" || final.length) {
    const words = final.length ? final.map((s) => s.words).join("; ") : batch.refusal;
    panel.replaceChildren(el("strong", {}, `Batch ${batch.id} ends: `),
      el("span", { "data-testid": "batch-ended" }, `${words}. Its other ${others} ${others === 1 ? "system stays" : "systems stay"} pending, to review one by one. `),
      el("span", { class: "actions" }, back));
  } else if (batch.state !== "open") {
    panel.replaceChildren(el("strong", {}, `Batch ${batch.id} `),
      el("span", { "data-testid": "batch-state" }, `was ${batch.state} already (${batch.accepted} accepted). `),
      el("span", { class: "actions" }, back));
  } else if (waiting.length) {
    panel.replaceChildren(el("strong", {}, `Sample of batch ${batch.id}: `),
      el("span", { "data-testid": "batch-waiting" }, `${waiting.map((s) => s.words).join("; ")}. `),
      el("span", { class: "actions" }, back));
  } else {
    const accept = el("button", { type: "button", class: "primary", "data-testid": "batch-accept" }, `accept the other ${others}`);
    const said = el("span", { "data-testid": "batch-plan" }, `Every sampled system is accepted: ${batch.plan}. `);
    accept.addEventListener("click", async () => {
      accept.disabled = true;
      try {
        const answer = await acceptBatch(batch.id);
        panel.replaceChildren(el("strong", {}, `Batch ${batch.id}: `),
          el("span", { "data-testid": "batch-accepted" }, `${answer.accepted} accepted after the sample (${batch.plan}). `),
          el("span", { class: "actions" }, back));
      } catch (err) {
        if (err instanceof ApiError && err.status === 409) await showBatchEnd(panel, batchId, queueUrl);
        else showError(`batch ${batch.id}: ${err.message}`);
      }
    });
    panel.replaceChildren(el("strong", {}, `Sample of batch ${batch.id} done: `), said,
      el("span", { class: "actions" }, accept, back));
    accept.focus();
  }
  panel.hidden = false;
  panel.scrollIntoView({ block: "nearest" });
}
