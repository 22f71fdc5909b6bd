// System page: every view of one multi-view system with its overlay, the 3D ball, the triangulation
// pairs, the pitch map, and the review decision (buttons and keys a / r / f, j / k to move).
// The page's query string holds the queue's filters; it is kept when moving between systems and
// going back to the queue, and forwarded to the API so prev_id / next_id follow that queue.
// Every write sends If-Match with the version the page drew (each view's `etag`, the system's `etag`);
// the writes to the views, their conflicts and the undo / redo writes are systemwrites.js. The history
// panel (history.js) lists the system's audit entries with a one-click revert. Field lines are edited in
// each view (lineseditor.js); the page keeps one undo / redo stack of its own edits (Ctrl+Z /
// Ctrl+Shift+Z: ball, exclusion, mirror, lines, decisions; each undo a write naming the entry it undoes).
// The page is the one controller of its state: it loads and renders a system, decides on it, moves on, and
// holds the key table; the views (overlay.js), the summary cards (systemcards.js), the map, a sequence's
// trajectory (sequence.js), the conflict notice and the history are their own modules. What differs between
// kinds of system is read from the system's data (its views, its `frame_index`), never from its kind's name.
import { ApiError, getMe, getSystem, listAudit, postReview, send } from "./api.js";
import { isTyping, viewColour, showError, clearError, STATUS_LABEL, toast } from "./format.js";
import { readState, apiFilters } from "./queuestate.js";
import "./overlay.js"; // defines <v3d-view>
import { isMirrorFlagged } from "./viewfacts.js";
import { renderBall, renderDoubts, renderPairs, renderStatus } from "./systemcards.js";
import { showConflict } from "./conflict.js";
import { HistoryPanel, describeState } from "./history.js";
import { KeyQueue, answersKey, dispatchKey, keysHelp, renderKeys } from "./keys.js";
import { busyWith, whileWorking, working } from "./busy.js";
import { EditHistory, lineKeys } from "./lineseditor.js";
import { ViewDecisions } from "./viewdecisions.js";
import { ZoomSync } from "./zoom.js";
import { chipLegend } from "./words.js";
import { ReviewPass, withPass } from "./pass.js";
import { AcceptGuard } from "./guard.js";
import { explainKeys } from "./keyreasons.js";
import { SystemPresence } from "./presence.js";
import { SequenceCard, inASequence } from "./sequence.js";
import { ViewWrites } from "./systemwrites.js";
import { CommentsCard } from "./comments.js";
import { askWhomToReturn, needsAChosenPerson } from "./returnto.js";
import "./pitchmap.js";
import "./trajectory.js";
import "./session.js";
import { keepDraft, restoreDrafts } from "./drafts.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);

class SystemPage {
  system = null;
  selected = -1;
  #busy = null; // ends the page's own work (busy.js) while it loads, decides or moves on
  sequence = new SequenceCard(this); // a frame of a sequence: its trajectory, its neighbours (sequence.js)
  writes = new ViewWrites(this); // the writes to the views, their ETags, conflicts and undo (systemwrites.js)

  /** True while the page loads a system, decides on it or moves on: the buttons and keys that would start another
   * of those wait (the key queue) or do nothing (a second click). Said on the body as the page's work (busy.js). */
  get busy() {
    return this.#busy !== null;
  }

  set busy(on) {
    if (on && !this.#busy) this.#busy = working("page");
    else if (!on && this.#busy) {
      const end = this.#busy;
      this.#busy = null;
      end();
    }
  }

  /** Whether a key can act now (the key queue's `ready`): a system is shown and taken in, and nothing the key's
   * effect depends on is on its way (a load, a decision, a write and its redraw, an undo, the pass's place, any
   * request of the page). A frame's image still arriving does not matter to a key, nor, to a key that moves or
   * grows the ball box, a nudge waiting for its pause; any other key first sends that nudge (and so waits for it). */
  keyReady(e) {
    if (!this.system || this.busy) return false;
    if (!NUDGE_KEYS.has(e.key)) for (const panel of $("views").children) panel.ball.flush();
    return busyWith().every((kind) => KEY_INDIFFERENT.has(kind));
  }

  /** Act on a key now (typed, or typed ahead and kept by the key queue): the accept guard's when it is open. */
  applyKey(e) {
    if (this.guard.open) this.guard.key(e);
    else dispatchKey(this.keys, e, toast); // Ctrl / Cmd chords only reach entries marked `ctrl`; a key that cannot act says why
  }

  /** Let every edit of this system reach the server before deciding on it or leaving it. */
  async settle() {
    for (const panel of $("views").children) panel.ball.flush();
    await Promise.allSettled([...this.writes.saves]);
  }

  constructor() {
    this.search = location.search;
    this.params = apiFilters(readState(location.search));
    $("prev").addEventListener("click", () => this.go(this.stepId(-1)));
    $("next").addEventListener("click", () => this.go(this.stepId(1)));
    for (const id of ["accept", "reject", "needs-fix"]) {
      $(id).addEventListener("click", (e) => this.review(e.currentTarget.dataset.status));
    }
    $("error-dismiss").addEventListener("click", clearError);
    this.comments = new CommentsCard(this); // comments pinned on the views; the hand-off (comments.js)
    $("comment").addEventListener("keydown", (e) => {
      if (e.key === "Escape") e.currentTarget.blur();
    });
    // the decision's comment as typed (not as the system's decision wrote it): kept when the session ends, warned of
    // before the page is left (drafts.js)
    keepDraft("comment", () => {
      const box = $("comment");
      return box.value.trim() && box.value !== box.defaultValue ? box.value : null;
    }, (text) => {
      $("comment").value = String(text);
    });
    $("views").addEventListener("ball-change", (e) => this.writes.saveBall(e.target, e.detail));
    $("views").addEventListener("lines-change", (e) => this.writes.saveLines(e.target, e.detail));
    this.undoStack = new EditHistory(
      (item, lines, undoOf, kind) => (item.kind === "lines" ? this.writes.undoLines(item, lines, undoOf, kind) : this.writes.undoWrite(item, undoOf, kind)),
      () => this.settle(),
      (kind) => toast(kind === "undo" ? "Nothing to undo: no edit of yours on this system (or the last undo failed)" : "Nothing to redo"),
      () => this.lastOwnEdit());
    $("views").addEventListener("mirror-request", (e) => this.writes.applyMirror(e.target, e.detail));
    $("views").addEventListener("exclusion-request", (e) => this.writes.setExclusion(e.target, e.detail));
    $("views").addEventListener("pointerdown", (e) => {
      const panel = e.target.closest("v3d-view");
      if (panel) this.select([...$("views").children].indexOf(panel));
    });
    $("trajectory").addEventListener("frame-select", (e) => this.go(e.detail.systemId));
    this.history = new HistoryPanel($("history"), {
      onReverted: (answer) => {
        toast("reverted");
        this.writes.afterWrite(this.system.id, null, answer);
      },
      onError: showError,
    });
    this.decisions = new ViewDecisions(this, toast);
    this.presence = new SystemPresence($("system-status")); // who it is assigned to, who else has it open
    this.zoom = new ZoomSync($("views"), document.querySelector(".topbar .navs"));
    this.pass = new ReviewPass(document.querySelector(".topbar .navs"), (id) => this.go(id)); // pass.js
    this.guard = new AcceptGuard(); // guard.js
    this.keys = explainKeys(this.keyTable(), this); // keyreasons.js: a key that cannot act says why
    this.keys.push(keysHelp(this.keys, "Keys of the system page", chipLegend("What the chips say")));
    renderKeys(this.keys, $("keys"));
    // keys typed while the page is still working are kept and applied in order once it can act on them (keys.js)
    this.keyQueue = new KeyQueue({ answers: (e) => answersKey(this.keys, e), ready: (e) => this.keyReady(e),
      apply: (e) => this.applyKey(e), say: toast });
    document.addEventListener("keydown", (e) => this.onKey(e));
    window.addEventListener("popstate", () => this.load(idFromPath(), false));
  }

  async load(id, push = false) {
    if (id === null) {
      showError("No system id in the address (expected /systems/<id>).");
      return;
    }
    this.busy = true;
    document.body.classList.add("loading");
    try {
      const system = await getSystem(id, this.params);
      if (push) history.pushState(null, "", `/systems/${encodeURIComponent(system.id)}${this.search}`);
      clearError();
      this.selected = -1;
      this.showUndoneHere(null); // an undo's notice names the system it brought the page back to: not this one
      this.render(system);
      if (!this.draftsBack) { // the first system shown: what was typed here when the session ended comes back
        this.draftsBack = true;
        const back = restoreDrafts();
        if (back.length) toast(`Put back as you had typed it before logging in again: ${back.map((n) => DRAFT_WORDS[n] || n).join(", ")}`);
      }
      window.scrollTo(0, 0);
      this.passReady = whileWorking("pass", this.followPass(system)); // j / k need the pass's neighbours
    } catch (err) {
      showError(err.message);
    } finally {
      this.busy = false;
      document.body.classList.remove("loading");
    }
  }

  /** Warm the browser's cache with the next system's frames, so that moving on is instant. */
  async prefetch(id) {
    if (id === null || id === undefined || this.prefetched === id) return;
    this.prefetched = id;
    try {
      const next = await getSystem(id, this.params, { background: true });
      for (const v of next.views) {
        if (v.image_url) new Image().src = v.image_url;
      }
    } catch {
      // only a cache warm-up: the real load reports its own errors
    }
  }

  async go(id) {
    if (id === null || id === undefined || this.busy) return;
    this.busy = true;
    await this.settle();
    this.busy = false;
    this.load(id, true);
  }

  /** The queue this system was opened from, with this system's row selected. */
  queueUrl() {
    return `/${withPass(this.search, null)}${this.system ? `#system-${this.system.id}` : ""}`;
  }

  /** The review pass (pass.js) follows the shown system: begun on the first system opened, its id then kept
   * in the address; prev / next become the pass's neighbours. */
  async followPass(sys) {
    try {
      const search = await this.pass.visit(sys, this.search);
      if (this.system?.id !== sys.id) return;
      if (search !== this.search) {
        this.search = search;
        history.replaceState(null, "", `/systems/${encodeURIComponent(sys.id)}${search}`);
      }
      $("queue-link").href = this.queueUrl();
      $("prev").disabled = this.stepId(-1) == null;
      $("next").disabled = this.stepId(1) == null;
      this.prefetch(this.pass.place?.next_pending_id);
    } catch (err) {
      showError(`review pass: ${err.message} (prev / next follow the queue)`);
    }
  }

  /** The system one step after (1) or before (-1) the shown one: in the pass, else in the queue. */
  stepId(step) {
    if (this.pass.place && this.pass.systemId === this.system?.id) return step > 0 ? this.pass.nextId() : this.pass.prevId();
    return step > 0 ? this.system?.next_id : this.system?.prev_id;
  }

  render(sys) {
    const sameSystem = this.system?.id === sys.id; // a redraw after an edit: the cards keep their places
    this.system = sys;
    for (const v of sys.views) this.writes.noteEtag(v.frame_id, v.etag);
    this.history.load(sys, this.params);
    $("queue-link").href = this.queueUrl();
    const game = sys.game || {};
    document.title = `${sys.name} · v3d review`;
    $("system-name").textContent = sys.name;
    $("system-game").textContent = [game.league, game.season, game.match].filter(Boolean).join(" · ");
    renderStatus(sys.review, sys.accepted_in_batch);
    this.pass.arrive(sys.id); // its place in the pass at once, before the visit answers
    this.presence.show(sys);
    $("prev").disabled = this.stepId(-1) == null; // in a pass: its neighbours (pass.js)
    $("next").disabled = this.stepId(1) == null;
    // the box holds the reviewer's own comment on the decision shown; a needs fix's note (and the fixed that answered
    // it) lives in the hand-off line, so that a re-review's decision never carries the earlier note as its own
    const decided = HANDED_OFF.has(sys.review?.status) ? "" : sys.review?.comment || "";
    $("comment").defaultValue = decided; // what is no draft (drafts.js): the text as the decision left it
    $("comment").value = decided;

    const tri = sys.triangulation || {};
    const ctx = { tau: tri.tau_px, rule: tri.rule, referenceWidth: tri.reference_width_px };
    const container = $("views");
    const panels = [...container.children];
    sys.views.forEach((view, index) => {
      let panel = panels[index];
      if (!panel) {
        panel = document.createElement("v3d-view");
        container.append(panel);
      }
      const viewDoubts = (sys.doubts || []).filter((d) => d.frame_id === view.frame_id);
      const names = Object.fromEntries(sys.views.map((x) => [x.frame_id, x.name]));
      panel.update(view, { ...ctx, index, viewCount: sys.views.length, doubts: viewDoubts, names });
      // doubtful views first, as they were when the system was opened: a fix never makes a card jump column
      if (!sameSystem || !panel.dataset.place) panel.dataset.place = panel.dataset.doubt;
      panel.selected = index === this.selected;
      this.decorate(panel, view);
    });
    for (const extra of panels.slice(sys.views.length)) extra.remove();
    this.zoom.drawBar();

    renderDoubts(sys, (i) => this.select(i));
    // a single view (a calibration dataset's frame) is reviewed for its calibration: no 3D ball to show
    const singleView = sys.views.length === 1;
    $("ball3d-card").hidden = singleView;
    $("pairs-card").hidden = singleView;
    renderBall(sys);
    renderPairs(sys);
    this.prefetch(this.pass.systemId === sys.id ? this.pass.place?.next_pending_id : sys.next_id);
    $("pitch-map").data = {
      ball3d: sys.ball3d,
      cameras: sys.views.map((v, i) => ({ label: `V${i + 1}`, name: v.name, colour: viewColour(i), position: v.camera_position })),
    };
    this.sequence.show(sys);
    this.comments.load(sys);
  }

  /** What the page adds to a view's panel after each rebuild: its decision bar, the synchronised zoom. */
  decorate(panel, view) {
    this.decisions.attach(panel, view);
    this.zoom.applyTo(panel);
  }

  /** Decide on the system (`status`: accepted, rejected, needs_fix) with the comment, after its edits reached the
   * server, and move on to the next system still pending (a 412: their decision drawn, the conflict notice). A needs
   * fix the server could return to no one asks whom it goes to (returnto.js) and is sent again to `assignee`. */
  async review(status, comment = null, ifMatch = null, assignee = null) {
    if (!this.system || this.busy) return;
    this.busy = true; // at once: a key typed after this one waits for the decision
    const me = await getMe().catch(() => null);
    if (me?.role === "annotator" && status !== "fixed") { // the API would answer 403: say what an annotator does instead
      this.busy = false;
      toast(ANNOTATOR_DECIDES_NOT);
      return;
    }
    const sys = this.system;
    const text = comment ?? $("comment").value.trim();
    const was = sys.review || {};
    if (ifMatch === null && was.status === status && (was.comment || "") === text) { // `a` again: nothing new to write
      this.busy = false;
      toast(`${sys.name} is already ${STATUS_LABEL[status].toLowerCase()}: nothing written.`);
      return;
    }
    try {
      await this.settle();
      // the accept guard (guard.js): open label doubts are listed first; Esc leaves the system pending. Waiting for the
      // person is not the page's work: keys typed ahead go to the guard (applyKey)
      if (status === "accepted" && this.guard.asks(this.system)) {
        this.busy = false;
        const go = await this.guard.ask(this.system);
        this.busy = true;
        if (!go) {
          toast(`${sys.name}: not accepted, still ${STATUS_LABEL[this.system.review?.status || "pending"].toLowerCase()}`);
          return;
        }
      }
      const { body: answer, etag, entry } = await postReview(sys.id, status, text, ifMatch ?? this.system.etag, assignee);
      if (entry) this.undoStack.push({ kind: "entry", systemId: sys.id, frameId: null, entry, what: `${sys.name}: ${STATUS_LABEL[status]}` });
      const current = this.system; // re-rendered by the edits just settled: its next_id is current
      clearError();
      renderStatus(answer || { status });
      // sent back as fixed: the next system of the person's To fix list, never another of the queue; else in a
      // pass: the next system of the pass still pending now (a fix never reorders the pass)
      await this.passReady;
      const fixing = status === "fixed";
      const place = fixing ? null : await this.pass.fresh(sys.id).catch(() => null);
      // a sampled system not accepted ends its batch (batch.js): the page stays and says so
      const endsBatch = place !== null && this.pass.batchId !== null && status !== "accepted";
      const next = fixing ? await nextToFix(sys.id) : endsBatch ? null : place ? place.next_pending_id : current.next_id;
      this.busy = false;
      const said = decisionWords(status, answer); // a needs fix says to whom it went
      if (next !== null && next !== undefined) {
        toast(`${sys.name}: ${said}${fixing ? "; the next system returned to you to fix is open" : ""}`);
        await this.load(next, true);
      } else {
        if (place) this.pass.showFinished(place, this.queueUrl());
        const last = fixing ? NOTHING_LEFT_TO_FIX : endsBatch ? BATCH_ENDS : place ? LAST_OF_PASS
          : "That was the last system of this queue.";
        toast(`${sys.name}: ${said}. ${last}`);
        if (this.system === current && etag) current.etag = etag; // the page stays: its next decision needs it
        if (this.system === current) { // the views' parts with no decision of their own read the system's now
          current.review = { ...(current.review || {}), ...(answer || { status }) };
          for (const panel of $("views").children) if (panel.view) this.decisions.attach(panel, panel.view);
        }
        this.history.load(current, this.params);
      }
    } catch (err) {
      if (err instanceof ApiError && err.status === 412) {
        this.busy = false;
        await this.reload();
        showConflict($("conflict"), { error: err, what: "the system's decision", viewName: null,
          mine: describeState({ review: { status, comment: text } }),
          reapply: (etag) => this.review(status, text, etag, assignee) });
      } else if (status === "needs_fix" && !assignee && needsAChosenPerson(err)) {
        this.busy = false;
        const why = String(err.body?.detail || "").replace(/^assignee: /, "").split(":")[0];
        const who = await askWhomToReturn(why).catch((e) => showError(e.message));
        if (who) await this.review(status, text, ifMatch, who);
        else toast(`${sys.name}: not returned, still ${STATUS_LABEL[sys.review?.status || "pending"].toLowerCase()}`);
      } else showError(err.message);
    } finally {
      this.busy = false;
    }
  }

  /** Say (`words`: what was undone, or null to hide it) that an undo brought the page back to the shown system, whose
   * name is outlined: until the page moves on, the next key acts here, not on the system the reviewer had gone to. */
  showUndoneHere(words) {
    const notice = $("undo-back");
    $("system-name").classList.toggle("undo-landed", Boolean(words));
    notice.hidden = !words;
    notice.replaceChildren();
    if (!words) return;
    const name = document.createElement("b");
    name.textContent = this.system?.name || "this system";
    notice.append("Back on ", name, ` after the undo (${words}): the next key acts on this system.`);
  }

  /** The undo item of the user's newest edit of the shown system that is not undone yet, read from the server's
   * history (what Ctrl+Z undoes after a reload, when the page's own stack is empty), or null. An undo or a revert
   * marks the entry it undid as undone (unless a newer entry undid it in turn: a redo); the server refuses (409) an edit someone changed since, said in the error bar. */
  async lastOwnEdit() {
    const sys = this.system;
    if (!sys) return null;
    const [me, page] = await Promise.all([getMe(), listAudit({ system_id: sys.id, limit: 50 })]).catch(() => [null, null]);
    if (!me || !page || this.system !== sys) return null;
    const undone = new Set();
    for (const entry of page.items) { // newest first: an undo undone by a newer entry (a redo) cancels nothing
      if (undone.has(entry.id)) continue;
      if (entry.reverts_id) {
        undone.add(entry.reverts_id);
        continue;
      }
      if (entry.actor !== me.name || !UNDOABLE.has(entry.action)) continue;
      return { kind: "entry", systemId: sys.id, frameId: entry.frame_id ?? null, entry: entry.id,
        what: entry.summary || entry.action };
    }
    return null;
  }

  /** Draw the current state of the shown system again (after a conflict, their state). */
  async reload() {
    if (!this.system) return;
    try {
      this.render(await getSystem(this.system.id, this.params));
    } catch (err) {
      showError(err.message);
    }
  }

  /** The view `s` acts on and its doubt: the selected view's snap (a label put on the suggested box or point),
   * else the only view with one. `s` only snaps: a mirror is `m`'s, an exclusion `x`'s (FIX_KEY). */
  fixTarget() {
    const panels = [...$("views").children];
    if (this.selected >= 0) {
      const panel = panels[this.selected];
      const doubt = panel?.fixableDoubt("s");
      return doubt ? [panel, doubt] : null;
    }
    const fixable = panels.map((p) => [p, p.fixableDoubt("s")]).filter(([, d]) => d);
    return fixable.length === 1 ? fixable[0] : null;
  }

  /** The view Enter confirms a placement in: the selected one when it has one pending, else the only one that
   * has (a label placed from a doubt's suggestion, not confirmed by a person yet). */
  placementTarget() {
    const panels = [...$("views").children];
    const selected = panels[this.selected];
    if (selected?.pendingPlacement) return selected;
    const pending = panels.filter((p) => p.pendingPlacement);
    return pending.length === 1 ? pending[0] : null;
  }

  /** The view `m` acts on: the selected one, else the only flagged one. */
  mirrorTarget() {
    const panels = [...$("views").children];
    if (this.selected >= 0) return panels[this.selected] || null;
    const flagged = panels.filter((p) => p.view && isMirrorFlagged(p.view));
    return flagged.length === 1 ? flagged[0] : null;
  }

  /** Select view `index`; `reveal`: scroll it into sight (a key chose it, maybe below the fold: the arrow keys then
   * move a box the reviewer sees). */
  select(index, reveal = false) {
    const panels = [...$("views").children];
    if (index < 0 || index >= panels.length) return;
    this.selected = index;
    panels.forEach((p, i) => (p.selected = i === index));
    if (reveal) revealBelowBar(panels[index]);
  }

  /** The page's keys: the one table the handler reads and the key card and `?` overlay show (keys.js). */
  keyTable() {
    const view = () => $("views").children[this.selected] || null;
    const nudge = (dx, dy, ds) => (e) => {
      const panel = view();
      if (!panel) return false;
      const step = e.shiftKey ? 5 : 1;
      return panel.ball.nudge(dx * step, dy * step, ds) !== false;
    };
    return [
      { keys: ["a"], does: "accept, next pending system (open doubts are listed first: Enter / Esc)", run: () => this.review("accepted") },
      { keys: ["r"], does: "reject, next pending system", run: () => this.review("rejected") },
      { keys: ["f"], does: "needs fix, next pending system", run: () => this.review("needs_fix") },
      { keys: ["j"], does: "next system of the pass", run: () => this.go(this.stepId(1)) },
      { keys: ["k"], does: "previous system of the pass", run: () => this.go(this.stepId(-1)) },
      { keys: [",", "."], does: "previous / next frame of a sequence (ISSIA)",
        run: (e) => (inASequence(this.system) ? this.go(this.sequence.neighbour(e.key === "." ? 1 : -1)) : false) },
      { keys: ["c"], does: "comment (Esc to leave)",
        run: () => ($("review-card").hidden ? "the decision's comment is a reviewer's (an annotator's page has none)" : $("comment").focus()) },
      { keys: ["u"], does: "back to the queue", run: () => this.settle().then(() => location.assign(this.queueUrl())) },
      { keys: ["o"], does: "hide / show the overlays",
        run: () => { document.body.classList.toggle("overlays-hidden"); } }, // look at the bare frames
      { keys: ["1", "2", "3", "4", "5", "6", "7", "8", "9"], show: ["1…9"], does: "select a view",
        run: (e) => this.select(Number(e.key) - 1, true) },
      { keys: ["ArrowLeft", "ArrowUp", "ArrowRight", "ArrowDown"], show: ["←↑→↓"],
        does: "move the selected view's ball box 1 px (Shift 5 px)",
        run: (e) => nudge(...{ ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] }[e.key], 0)(e) },
      { keys: ["+", "="], show: ["+"], does: "grow its box", run: (e) => nudge(0, 0, 0.5)(e) },
      { keys: ["-"], does: "shrink its box", run: (e) => nudge(0, 0, -0.5)(e) },
      ...lineKeys(view, this.undoStack), // before the ball's Del: a selected line point goes first
      { keys: ["Delete", "Backspace"], show: ["Del"], does: "no ball in this view (remove its label)",
        run: () => view()?.removeLabel() ?? false },
      { keys: ["z"], does: "restore its imported label", run: () => view()?.restoreLabel() ?? false },
      { keys: ["Enter"], does: "confirm the pending placement (selected view, or the only one with a suggested label)",
        run: () => Boolean(this.placementTarget()?.confirmPlacement()) },
      { keys: ["s"], does: "snap the ball label to a doubt's suggestion (selected view, or the only one with a snap)",
        run: () => {
          const target = this.fixTarget();
          return Boolean(target && target[0].applyFix(target[1]));
        } },
      { keys: ["x"], does: "exclude the selected view from the 3D ball, or restore it",
        run: () => Boolean(view() && this.system.views.length > 1 && view().toggleExclusion()) },
      { keys: ["m"], does: "apply mirrored labels (selected flagged view, or the only one)",
        run: () => Boolean(this.mirrorTarget()?.requestMirror()) },
      ...this.decisions.keyEntries(() => view() || (this.system?.views.length === 1 ? $("views").children[0] : null)),
      ...this.zoom.keyEntries(),
      ...this.comments.keyEntries(),
    ];
  }

  onKey(e) {
    if (isTyping(e)) return;
    this.keyQueue.take(e);
  }
}

/** The keys that move or grow the selected view's ball box: they add to a nudge waiting for its pause. */
const NUDGE_KEYS = new Set(["ArrowLeft", "ArrowUp", "ArrowRight", "ArrowDown", "+", "=", "-"]);
/** The page's work a key does not wait for (busy.js): a frame's image arriving, a nudge's pause (see keyReady), the
 * keys typed ahead themselves. */
const KEY_INDIFFERENT = new Set(["image", "nudge", "keys"]);

/** The statuses whose comment is the hand-off's note (shown in the Comments card), not a comment to decide with. */
const HANDED_OFF = new Set(["needs_fix", "fixed"]);
/** The page's drafts (drafts.js) in words, as the toast that puts them back names them. */
const DRAFT_WORDS = { comment: "your decision's comment", pin: "the comment you were pinning" };

/** The audit actions a person's Ctrl+Z undoes (the edits of the page's undo stack). */
const UNDOABLE = new Set(["ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion", "view.review",
  "view.calibration_review", "system.review"]);

/** What `a`, `r` or `f` say on an annotator's page (deciding is a reviewer's; the API would refuse it). */
export const ANNOTATOR_DECIDES_NOT = "Accepting, rejecting and returning systems is for reviewers: as an annotator you "
  + "fix labels, and send back as fixed a system returned to you.";

/** A decision in words: a needs fix names the person it went to ("returned to ana by rev: ..."). */
function decisionWords(status, answer) {
  if (answer?.handoff) return answer.handoff;
  if (status === "needs_fix" && answer?.returned_to) return `needs fix, returned to ${answer.returned_to}`;
  return STATUS_LABEL[status];
}

/** The toast of the last "Send back as fixed" of a person's To fix list. */
export const NOTHING_LEFT_TO_FIX = "Nothing else is returned to you to fix.";

/** The next system of the caller's To fix list (GET /api/handoffs/mine, the oldest hand-off first) after sending
 * `doneId` back as fixed, or null when none is left (or the list cannot be read: the page then stays). */
async function nextToFix(doneId) {
  const work = await send("GET", "/api/handoffs/mine").catch(() => null);
  return (work?.to_fix_ids || []).find((id) => id !== doneId) ?? null;
}

/** The toast of a sampled system's decision that is not an accept: its batch ends (batch.js). */
export const BATCH_ENDS = "The batch ends: a sampled system was not accepted.";
/** The toast of the last decision of a pass (nothing pending left after the system). */
export const LAST_OF_PASS = "Nothing pending is left in this pass.";

/** Scroll the window so that `card` is wholly seen below the sticky top bar, or, taller than the room there, its top
 * just under the bar; a card already wholly seen stays where it is. */
function revealBelowBar(card) {
  const barBottom = Math.max(0, document.querySelector(".topbar")?.getBoundingClientRect().bottom ?? 0);
  const r = card.getBoundingClientRect();
  if (r.top >= barBottom && r.bottom <= innerHeight) return;
  const gap = 8;
  const dy = r.top < barBottom || r.height > innerHeight - barBottom - 2 * gap ? r.top - barBottom - gap : r.bottom - innerHeight + gap;
  window.scrollBy({ top: dy, behavior: "instant" });
}

function idFromPath() {
  const m = location.pathname.match(/\/systems\/([^/]+)\/?$/);
  return m ? decodeURIComponent(m[1]) : null;
}


const page = new SystemPage();
page.load(idFromPath());
