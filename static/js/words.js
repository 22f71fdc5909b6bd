// The words of the review pages: what every machine code shown on a page reads as, one table, so
// that a page never shows a raw token. WRITTEN FROM app/services/wording/words.py
// (python -m app.services.wording.words > static/js/words.js); tests/services/wording/test_words.py checks that
// the two agree. Do not edit the table here.

export const WORDS = /*WORDS*/{
 "doubt": {
  "mirrored_labels": {
   "tone": "bad",
   "chip": "mirrored labels",
   "means": "the view's field lines look labelled left for right; m applies the mirrored labels"
  },
  "ball_off_consensus": {
   "tone": "bad",
   "chip": "ball off consensus",
   "means": "the view's ball label is far from the ball the other views agree on; s snaps it to their box, x leaves the view out"
  },
  "ball_missing": {
   "tone": "bad",
   "chip": "ball missing",
   "means": "the view has no ball label but the other views' ball is inside it; s places their box"
  },
  "views_disagree": {
   "tone": "bad",
   "chip": "views disagree",
   "means": "the ball labels cannot all be right and the wrong one cannot be told"
  },
  "near_duplicate_view": {
   "tone": "bad",
   "chip": "near-duplicate view",
   "means": "two views from nearly the same place: this one adds no depth; x leaves it out"
  },
  "calibration_refused": {
   "tone": "bad",
   "chip": "no camera",
   "means": "the view's field lines fit no camera, so its labels cannot be checked"
  },
  "below_admission": {
   "tone": "bad",
   "chip": "below admission",
   "means": "the camera fits its lines less well than the admission threshold"
  },
  "rig_assisted": {
   "tone": "info",
   "chip": "at the game's camera spot",
   "means": "rig position: the camera was fitted where a camera of the game is known to stand"
  },
  "few_lines": {
   "tone": "info",
   "chip": "few lines",
   "means": "too few field-line classes to fix the camera reliably"
  },
  "suggested_label": {
   "tone": "info",
   "chip": "placement to confirm",
   "means": "the ball label was placed from a doubt's fix; Enter confirms it"
  },
  "ball_detected": {
   "chip": "ball detected",
   "means": "the view has no ball label but a detector found the ball where the other views put it, at a ball's size; s places the detector's box"
  },
  "detection_off_label": {
   "chip": "detector disagrees",
   "means": "a detector found the ball where the other views put it, away from this view's label"
  }
 },
 "flag": {
  "probably_mirrored": {
   "tone": "bad",
   "chip": "mirrored labels",
   "means": "the field lines are probably labelled left for right"
  },
  "rig_assisted": {
   "tone": "info",
   "chip": "at the game's camera spot",
   "means": "rig position: fitted where a camera of the game is known to stand"
  },
  "player_assisted": {
   "tone": "info",
   "chip": "placed by players",
   "means": "fitted to where the players it shares with the well-lined views stand (their foot points, drawn as small markers), with whatever lines it has"
  },
  "learned_prior": {
   "chip": "helped by the usual cameras",
   "means": "learned prior: fitted with what the dataset's cameras usually are (where they stand, how they zoom)"
  },
  "radial_prior": {
   "chip": "lens prior",
   "means": "the lens distortion was fitted under the learned prior"
  },
  "radial_distortion": {
   "chip": "lens distortion",
   "means": "the lens distortion was fitted"
  },
  "few_lines": {
   "tone": "info",
   "chip": "few lines",
   "means": "fewer than 4 field-line classes"
  },
  "given_camera": {
   "chip": "given camera",
   "means": "the camera came with the data, not from its lines"
  },
  "ball_assisted": {
   "chip": "ball-assisted",
   "means": "calibrated again from the ball seen by the other cameras"
  },
  "ball_bundle": {
   "chip": "refined with the ball",
   "means": "ball bundle: refined together with the other cameras from their lines and the ball they all see"
  }
 },
 "placement": {
  "ball_off_consensus:off_consensus": {
   "chip": "the other views' ball",
   "means": "moved to where the other labelled views agree on the ball"
  },
  "ball_missing:consensus": {
   "chip": "the other views' ball",
   "means": "placed where the labelled views agree on the ball"
  },
  "ball_missing:epipolar_box": {
   "chip": "a guess on one ray",
   "means": "a guess along the one labelled view's ray, on the grass"
  },
  "ball_missing:pairing": {
   "chip": "where detections put the ball",
   "means": "placed where a label and detectors' boxes in other views put the ball"
  },
  "ball_detected:consensus": {
   "chip": "detector, views agree",
   "means": "a detector's box where the labelled views agree on the ball"
  },
  "ball_detected:one_view": {
   "chip": "detector, two detected views",
   "means": "a detector's box whose ray meets the one labelled view's and a second detected view's at one ball"
  },
  "ball_detected:one_ray": {
   "chip": "detector, one labelled ray",
   "means": "a detector's box whose ray meets the one labelled view's in the play volume at a ball's size, with no third view missing it"
  },
  "ball_detected:detections_agree": {
   "chip": "detectors agree",
   "means": "detectors' boxes in two or more views that meet at one ball of a ball's size, no labelled view taking part"
  },
  "ball_detected:weak_ray": {
   "chip": "detector, unsure labelled ray",
   "means": "the only detector's box near the ray of a label whose camera takes no part, meeting it at a ball's size; the box cannot make a 3D ball"
  },
  "ball_detected:weak_view": {
   "chip": "detector, unsure camera",
   "means": "the only detector's box where the ball the other views place projects (or on the one labelled view's ray) in a view whose camera takes no part, within that camera's uncertainty"
  }
 },
 "flag_prefix": {
  "ignored_class": {
   "chip": "ignores {}",
   "means": "that field-line class disagrees with every camera fitting the others, so the fit leaves it out"
  }
 },
 "note": {
  "not_calibrated": {
   "tone": "bad",
   "chip": "no camera",
   "means": "the view has no calibrated camera"
  },
  "not_admitted": {
   "tone": "bad",
   "chip": "below admission",
   "means": "the camera fits its lines less well than the admission threshold; under the rule by evidence it still joins the 3D ball, weighed by its uncertainty, while it fits at least half of its lines"
  },
  "excluded": {
   "tone": "bad",
   "chip": "excluded",
   "means": "a reviewer left the view out of the 3D ball (x restores it)"
  },
  "error_above_tau": {
   "tone": "bad",
   "chip": "error > τ",
   "means": "the 3D ball, drawn into the view, lies farther from its ball label than the limit (reprojection error above τ)"
  },
  "no_ball3d": {
   "chip": "no 3D ball",
   "means": "no pair of views agrees on a ball"
  },
  "without_ball": {
   "chip": "without ball",
   "means": "views without a ball label"
  }
 },
 "term": {
  "jac": {
   "chip": "Lines fit",
   "means": "JaC@γ %: the share of the pitch model the camera draws onto the annotated field lines (Jaccard index within γ % of the image diagonal; 100 % is a perfect fit)"
  },
  "camera_sigma": {
   "chip": "Camera unsure by",
   "means": "Camera ±: the camera's standard deviations from the line fit: where it stands x/y/z (m), pan/tilt/roll (degrees), zoom as focal length (px); — where the lines leave it open"
  },
  "reprojection_error": {
   "chip": "Ball off by",
   "means": "reprojection error: how far the 3D ball, drawn into this view, lies from its ball label (px of the frame)"
  },
  "tau": {
   "chip": "allowed",
   "means": "τ (tau): the reprojection error limit, the farthest a view's label may lie from the 3D ball and still agree"
  },
  "pin": {
   "chip": "pinned at",
   "means": "V<n> (x, y): the view and the pixel the comment is pinned to (x from the frame's left edge, y from its top)"
  }
 },
 "triangulation": {
  "triangulated": {
   "chip": "triangulated",
   "means": "at least one pair of views agrees on the ball"
  },
  "insufficient_views": {
   "chip": "too few views",
   "means": "fewer than two views with a ball label whose cameras may make a ball (admitted, or fitting most of their own lines)"
  },
  "no_pair_kept": {
   "chip": "no pair kept",
   "means": "every pair of views was dropped"
  }
 },
 "pair_reason": {
  "degenerate": {
   "chip": "rays identical",
   "means": "the two rays are the same line"
  },
  "point_at_infinity": {
   "chip": "rays parallel",
   "means": "the two rays meet at infinity"
  },
  "behind_camera": {
   "chip": "behind a camera",
   "means": "the rays meet behind one of the cameras"
  },
  "baseline_below_min": {
   "chip": "cameras too close",
   "means": "the camera centres are closer than the minimum baseline"
  },
  "parallax_below_min": {
   "chip": "angle too small",
   "means": "the rays meet at too small an angle to fix the depth"
  },
  "error_above_tau": {
   "chip": "error > τ",
   "means": "the pair's reprojection error is above the limit τ"
  },
  "outside_play_volume": {
   "chip": "outside the pitch",
   "means": "the rays meet where no ball can be"
  },
  "weak_calibrations": {
   "chip": "weak cameras",
   "means": "neither camera is sure enough to make a ball"
  },
  "outweighed": {
   "chip": "outweighed",
   "means": "pairs of surer cameras agree on another ball"
  },
  "players_disagree": {
   "chip": "players disagree",
   "means": "the two cameras put the players both views see in different places: one camera is wrong (mirrored, misplaced) or the views are not of one instant"
  },
  "beyond_joint_sigma": {
   "chip": "disagrees",
   "means": "the pair's point lies off the ball the other pairs agree on, beyond their joint uncertainty"
  },
  "sigma_above_bound": {
   "chip": "too uncertain",
   "means": "the ball these pairs make is less certain than the bound (V3D_BALL_MAX_SIGMA_M)"
  },
  "lone_pair_at_tau_edge": {
   "chip": "meets at τ's edge",
   "means": "the ball would rest on this one pair, whose rays meet only near the limit τ: right pairs meet well within it, rays that cross by chance (a replay of another instant, a label on another object) anywhere in it, and no other view checks which this is; place or confirm a third view"
  },
  "outside_consensus": {
   "chip": "outside the consensus",
   "means": "a view of this pair is not among the most views that agree on one ball (each within τ of it): a replay of another instant, or a view whose label or camera is off; the pair is left out before the pairs are weighed"
  }
 },
 "rule": {
  "max_scaled_1920": {
   "chip": "worse view, at 1920 px width",
   "means": "a pair's error is the larger of its two views' errors, each scaled to a 1920-px-wide image"
  },
  "mean_scaled_1920": {
   "chip": "mean of the views, at 1920 px width",
   "means": "a pair's error is the mean of its two views' errors, each scaled to a 1920-px-wide image"
  },
  "max_px": {
   "chip": "worse view, in its pixels",
   "means": "a pair's error is the larger of its two views' errors, in their own pixels"
  }
 },
 "calibration": {
  "calibrated": {
   "chip": "calibrated",
   "means": "a camera fits the view's field lines"
  },
  "refused": {
   "chip": "refused",
   "means": "no camera fits the view's field lines"
  },
  "computed": {
   "chip": "computed",
   "means": "fitted by v3d to the current field lines"
  },
  "imported": {
   "chip": "imported",
   "means": "read from an export"
  },
  "edited": {
   "chip": "edited",
   "means": "set by a person"
  }
 },
 "refusal": {
  "few_constraints": {
   "chip": "too few lines",
   "means": "fewer independent line constraints than a camera has unknowns"
  },
  "parallel_lines": {
   "chip": "parallel lines",
   "means": "every labelled line is parallel on the pitch and no circle or goal fixes the view"
  },
  "collinear_points": {
   "chip": "collinear points",
   "means": "every labelled point lies on one image line"
  },
  "solver_failed": {
   "chip": "solver failed",
   "means": "the camera fit raised an error"
  },
  "no_camera_fits": {
   "chip": "no camera fits",
   "means": "every starting camera failed or put the pitch behind the camera"
  },
  "residual_too_high": {
   "chip": "a line off",
   "means": "one labelled line stays too far from its pitch line under every camera"
  },
  "centre_misfit": {
   "chip": "misfit at rig position",
   "means": "the labels do not fit a camera at the game's known camera position"
  },
  "no_rig_position": {
   "chip": "no rig position",
   "means": "the game has no camera position yet (no well-calibrated frame to estimate it)"
  },
  "no_lines": {
   "chip": "no field lines",
   "means": "the static camera has no field lines to calibrate from"
  },
  "below_admission": {
   "chip": "below admission",
   "means": "the static camera fits its lines less well than the admission threshold"
  },
  "not_in_calibration_json": {
   "chip": "no given camera",
   "means": "the sequence's calibration file gives no camera for this view"
  },
  "unspecified": {
   "chip": "refused",
   "means": "refused without a recorded reason"
  }
 }
}/*END*/;

/** The doubt kinds that accuse a label, in the contract's order (app/geometry/doubts/contract.py LABEL_KINDS): the
 * queue counts, filters and sorts by them. */
export const LABEL_KINDS = /*LABEL_KINDS*/["mirrored_labels", "ball_off_consensus", "ball_missing", "views_disagree", "near_duplicate_view", "ball_detected"]/*END*/;

/** The doubt kinds whose suggested box is a detector's, their evidence naming the detector and its score
 * (app/geometry/doubts/contract.py DETECTOR_KINDS): the view draws that box in the detections' colour, and the fix
 * says whose box it places. */
export const DETECTOR_KINDS = /*DETECTOR_KINDS*/["ball_detected"]/*END*/;

/** How the system page draws a doubt of each kind (app/services/wording/words.py DOUBT_DRAWING): the test ids of its
 * message and fix button, the field of the view's calibration whose sentence its message shows (null: the doubt's
 * own), whether it offers to confirm a suggested placement. */
export const DOUBT_DRAWING = /*DOUBT_DRAWING*/{
 "mirrored_labels": {"message_id": "view-mirror-evidence", "sentence_from": "mirror_evidence", "fix_id": "apply-mirror", "confirms_placement": false},
 "ball_off_consensus": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "ball_missing": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "views_disagree": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "near_duplicate_view": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "ball_detected": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "calibration_refused": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "below_admission": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "rig_assisted": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "few_lines": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false},
 "suggested_label": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": true},
 "detection_off_label": {"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false}
}/*END*/;

/** How a doubt of a kind the table does not know is drawn. */
export const DOUBT_DRAWING_DEFAULT = /*DOUBT_DRAWING_DEFAULT*/{"message_id": "view-doubt-message", "sentence_from": null, "fix_id": "apply-fix", "confirms_placement": false}/*END*/;

/** How a doubt of `kind` is drawn: its entry of DOUBT_DRAWING, else the default. */
export const doubtDrawing = (kind) => DOUBT_DRAWING[kind] || DOUBT_DRAWING_DEFAULT;

const humanise = (code) => String(code).replaceAll("_", " ");

/** The entry {chip, means} of `code` in `group` (a flag with a value: its prefix's entry, the value put in);
 * an unknown code reads as its words (underscores as spaces), never as the raw token. */
export function word(group, code) {
  const table = WORDS[group] || {};
  if (table[code]) return table[code];
  if (group === "flag" && typeof code === "string" && code.includes(":")) {
    const [prefix, value] = [code.slice(0, code.indexOf(":")), code.slice(code.indexOf(":") + 1)];
    const p = WORDS.flag_prefix[prefix];
    if (p) return { chip: p.chip.replace("{}", value), means: `${value}: ${p.means}` };
  }
  return { chip: humanise(code ?? ""), means: "" };
}

/** The chip words of `code` in `group`. */
export const chip = (group, code) => word(group, code).chip;

/** The class of the chip of `code` in `group`: "chip" with its tone (bad: red, info: blue; none: amber), the same on
 * every page and in the legend. */
export function chipClass(group, code) {
  const tone = word(group, code).tone;
  return tone ? `chip ${tone}` : "chip";
}

/** A height above the grass in words: "height 9.0 m" (the SoccerNet world's z points down: a height is -z). */
export function heightText(z, digits = 1) {
  if (typeof z !== "number" || !Number.isFinite(z)) return "height —";
  const h = (-z).toFixed(digits);
  return `height ${Number(h) === 0 ? (0).toFixed(digits) : h} m`;
}

/** tau named where it is shown: "reprojection error limit τ = 20.0 px". */
export function tauText(tau, digits = 1) {
  const shown = typeof tau === "number" && Number.isFinite(tau) ? tau.toFixed(digits) : "?";
  return `reprojection error limit τ = ${shown} px`;
}

/** The legend's entries of the chips a page shows: [[chip, means, tone], ...] of the given groups, each chip once. */
export function legendEntries(groups = ["doubt", "note", "flag", "flag_prefix"]) {
  const seen = new Set();
  return groups.flatMap((g) => Object.values(WORDS[g] || {}).map((e) => [e.chip.replace("{}", "…"), e.means, e.tone]))
    .filter(([c]) => !seen.has(c) && seen.add(c));
}

/** The legend of every chip (data-testid="chip-legend"): a chip and its meaning per entry. */
export function chipLegend(title = "Chips", groups = undefined) {
  const box = document.createElement("section");
  box.className = "chip-legend";
  box.dataset.testid = "chip-legend";
  const h = document.createElement("h3");
  h.textContent = title;
  const grid = document.createElement("div");
  grid.className = "chip-legend-grid";
  for (const [c, means, tone] of legendEntries(groups)) {
    const item = document.createElement("div");
    item.dataset.testid = "chip-legend-entry";
    const span = document.createElement("span");
    span.className = tone ? `chip ${tone}` : "chip";
    span.textContent = c;
    item.append(span, ` ${means}`);
    grid.append(item);
  }
  if (title) box.append(h);
  box.append(grid);
  return box;
}
