// A system that is one frame of a sequence (its `frame_index` is set: ISSIA's static cameras, the only import
// that makes them): the sequence's ball trajectory over time in its card (trajectory.js), the current frame
// marked, the fitted track on the pitch map, and the systems of the frames before and after (keys , and .).
// The page asks whether a system is in a sequence from the data, never from its kind's name.

import { getTrajectory } from "./api.js";
import { showError } from "./format.js";

const $ = (id) => document.querySelector(`[data-testid="${id}"]`);

/** The system is one frame of a sequence (its `frame_index` is set), so it has a trajectory and neighbours. */
export function inASequence(sys) {
  return Number.isInteger(sys?.frame_index);
}

export class SequenceCard {
  #page;
  trajectory = null; // the last trajectory read (GET /api/games/{id}/trajectory)

  /** `page`: the system page (its shown `system`). */
  constructor(page) {
    this.#page = page;
  }

  /** Show the card of `sys`'s sequence, or hide it outside one. The trajectory is re-read after every render,
   * so an edit's re-fit shows; errors go to the page's error bar. */
  async show(sys) {
    const inSequence = inASequence(sys);
    $("trajectory-card").hidden = !inSequence;
    if (!inSequence) return;
    try {
      const trajectory = await getTrajectory(sys.game.id);
      if (this.#page.system !== sys) return; // another system was rendered meanwhile
      this.trajectory = trajectory;
      $("trajectory").data = { trajectory, current: sys.frame_index };
      const track = trajectory.frames.map((f) => f.ball3d_smoothed).filter((p) => Array.isArray(p));
      $("pitch-map").data = { ...$("pitch-map").data, track };
    } catch (err) {
      showError(err.message);
    }
  }

  /** The id of the system ``step`` frames away from the shown one in its sequence (null outside it, or past
   * an end). */
  neighbour(step) {
    const frames = this.trajectory?.frames || [];
    const i = frames.findIndex((f) => f.system_id === this.#page.system?.id);
    return i >= 0 && frames[i + step] ? frames[i + step].system_id : null;
  }
}
