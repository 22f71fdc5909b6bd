"""What backs a system's 3D ball: the evidence beside the two rays that make it, and the tier it puts the ball in
(``vouched``, ``unconfirmed``, ``doubted``, ``none``: ``app.db.models.enums.BallEvidence``), with the reasons a
reviewer reads.

Two labelled rays that meet within tau make a 3D ball, but they cannot tell it from a wrong one: a label on another
object, a replay of another instant or a camera off along the epipolar line still gives two rays that meet (the
SoccerNet-v3D paper's triangulation, Sec. 3, checks nothing else). Evidence independent of those two rays can:

* **further views**: a third (fourth ...) labelled view whose ray meets the same ball within its joint sigma (the
  rule by evidence keeps only such pairs, ``app.geometry.evidence.judge_by_evidence``): a wrong label or a
  desynchronised replay would need a second wrong label at the same wrong place;
* **the detector at each label** (:func:`detection_at_label`): an imported detection whose centre lies within the
  label's radius and whose size agrees with the label's; it vouches for the image content at the label (a label where
  no ball is), not for the instant;
* **the players**: both cameras of a kept pair place the players both views see at the same place
  (``app.geometry.calibration.players.pair_players_disagreement``, at least three shared players): a second look at
  the two cameras, independent of the ball;
* **another view that sees it** (:func:`detection_at_ball`): a detection, or a person's label, in a view outside the
  ball's pairs where the 3D ball projects, at a ball's size there: a third ray;
* **the label's size at the ball's depth** (:func:`label_size_ratio`): a label's box against the silhouette of a
  0.22 m sphere at the 3D ball (Hartley and Zisserman 8.3): measured, it does not separate right balls from wrong ones
  (labels' sizes err by up to half; ``benchmarks/VOUCH.md``), so the rule leaves it out and the recomputation does
  not compute it;
* **the ball's sigma** (``app.geometry.evidence.kept_pairs_sigma_m``): how far the ball may lie off by its views'
  own uncertainty.

Which of these separate right balls from wrong ones, and the thresholds, were measured on the shared sets with a
truth (``benchmarks/VOUCH.md``, ``benchmarks/ball_evidence.py``, which names the sets that chose and those only read).
The rule is :func:`ball_evidence`; :data:`RULE_VERSION` is stored with the derived rows (folded into
``app.services.derivation.recompute.DERIVED_VERSION``), so a change of rule recomputes every system.

Pure: numpy only. World frame: SoccerNet (metres, origin at the centre spot, z down); pixels of each view's own
image, origin at its top-left corner.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations
from typing import Sequence

import numpy as np

from app.geometry.ball import sphere_image_box
from app.geometry.camera import Camera

#: The rule's version: raise it with any change of :func:`ball_evidence` or its thresholds (it is part of the
#: derived version, so every stored system is recomputed).
RULE_VERSION = 2  # 2: a label copied from a detection's box is not confirmed by that detection

#: A detection confirms a label when its centre lies within this fraction of the label's radius of the label's centre.
DETECTION_CENTRE_RADII = 1.0
#: ... and its diameter is within this fraction of the label's (|ratio - 1|); and a detection or a label in another
#: view is the ball's only when its diameter is within this fraction of the sphere's silhouette there. Set a priori,
#: not fitted, as the doubts' ``doubt_detection_size_tolerance``: a detector's box sides err by up to about 20 % (the
#: shared detector sets' README) and the depth by about as much.
DETECTION_SIZE_TOLERANCE = 0.5
#: A ball with at least this many views every two of which make a kept pair is vouched for by its views alone.
AGREEING_VIEWS = 3
#: A ball whose sigma (m) is above this is vouched for by nothing but further agreeing views: its own views leave it
#: loose by the distance a wrong ball is counted from (1 m), which one more pixel check cannot tie down.
VOUCH_MAX_SIGMA_M = 1.0
#: Two views whose labels the detector confirms and whose cameras agree on the players vouch for their ball only when
#: their pair error is at most this fraction of tau (right pairs: 95 % within 0.26 tau on the sets that chose it; a
#: desynchronised replay's ray meets the other anywhere within tau) ...
TWO_VIEW_MAX_ERROR_TAU = 1 / 3
#: ... and the ball's sigma is at most this (m): the right distance, 0.5 m.
TWO_VIEW_MAX_SIGMA_M = 0.5

TIER_VOUCHED = "vouched"
TIER_UNCONFIRMED = "unconfirmed"
TIER_DOUBTED = "doubted"
TIER_NONE = "none"


@dataclass(frozen=True)
class ViewFacts:
    """One view of the 3D ball (a view in one of its kept pairs).

    Attributes:
        name: the view's name as a reviewer reads it ("V1", the frame's name).
        detected: whether an imported detection confirms the label (:func:`detection_at_label`); None when the view
            has no prediction at all (no detector was run on it: it says nothing).
    """

    name: str
    detected: bool | None = None


@dataclass(frozen=True)
class OtherView:
    """A calibrated view outside the ball's kept pairs with a detector's prediction: the one nearest where the 3D ball
    projects (:func:`detection_at_ball`).

    Attributes:
        name: the view's name ("V3").
        distance_1920: its centre's distance (px at 1920 width) from the centre of the ball's silhouette there.
        size_ratio: its diameter over the silhouette's.
        depth_1920: how far (px at 1920 width) the view sees the ball move when it moves 1 m along the ray of any
            view of its pairs, the least over them (:func:`depth_shift_px`): a view beside one of them (a near
            duplicate) sees a ball wrong along that ray where the right one is, and checks nothing.
    """

    name: str
    distance_1920: float
    size_ratio: float
    depth_1920: float = math.inf


@dataclass(frozen=True)
class BallFacts:
    """The evidence behind one system's 3D ball (what :func:`ball_evidence` reads).

    Attributes:
        has_ball: the system has a stored 3D ball.
        views: the views of its kept pairs.
        doubted: the names of those views a label doubt of the system names (a doubt naming no view names them
            all).
        players_pairs: kept pairs whose two cameras place the players both views see in agreement (at least three
            shared players); the service counts them only where the detector confirms every label (rule 3, the one
            rule that reads them), 0 elsewhere.
        sigma_m: the ball's sigma (metres along its least certain direction), None when unknown.
        others: the calibrated views outside the kept pairs that have a prediction, each with the one nearest the
            ball's projection.
        pair_error_tau: the largest pair error of its kept pairs as a fraction of tau (by the triangulation's
            rule, ``app.geometry.pair_error``); None when unknown.
        agreeing: the most views every two of which make a kept pair (:func:`agreeing_views`): three views of
            which two pairs are kept do not all agree (a replay of another instant may meet the action's ray along
            its epipolar line while missing the other replay's).
        labelled_others: the views outside the kept pairs with a ball box a person placed and a camera (not
            excluded), each with its box against the ball's projection (as a detection, :func:`detection_at_ball`).
        tau_px: the triangulation's tau (px at 1920 width), the tolerance another view's box is read with.
    """

    has_ball: bool
    views: tuple[ViewFacts, ...] = ()
    doubted: tuple[str, ...] = ()
    players_pairs: int = 0
    sigma_m: float | None = None
    others: tuple[OtherView, ...] = ()
    pair_error_tau: float | None = None
    agreeing: int = 0
    labelled_others: tuple[OtherView, ...] = ()
    tau_px: float = 20.0


def agreeing_views(pairs: Sequence[tuple[object, object]]) -> int:
    """The size of the largest set of views every two of which are a pair of ``pairs`` (the largest clique of the
    graph whose edges are the kept pairs; 0 without a pair). Exhaustive over the views' subsets, largest first: a
    multi-view system has a handful of views (SoccerNet-v3: an action and at most a few replays)."""
    views = sorted({v for p in pairs for v in p}, key=repr)
    edges = {frozenset(p) for p in pairs}
    for size in range(len(views), 1, -1):
        for subset in combinations(views, size):
            if all(frozenset((a, b)) in edges for a, b in combinations(subset, 2)):
                return size
    return 0


def detection_at_label(label_box: Sequence[float], detections: Sequence[Sequence[float]]) -> bool:
    """Whether any detection box confirms the label box: its centre within :data:`DETECTION_CENTRE_RADII` of the
    label's radius of the label's centre, and its diameter ``(w + h) / 2`` within :data:`DETECTION_SIZE_TOLERANCE`
    of the label's.

    Args:
        label_box: (4,) ``[x1, y1, x2, y2]`` px of the view's image.
        detections: (n, 4) boxes likewise, any detector's.
    """
    lb = np.asarray(label_box, dtype=float).reshape(4)
    d_label = ((lb[2] - lb[0]) + (lb[3] - lb[1])) / 2
    if not d_label > 0:
        return False
    centre = (lb[:2] + lb[2:]) / 2
    for box in detections:
        b = np.asarray(box, dtype=float).reshape(4)
        d = ((b[2] - b[0]) + (b[3] - b[1])) / 2
        if (np.linalg.norm((b[:2] + b[2:]) / 2 - centre) <= DETECTION_CENTRE_RADII * d_label / 2
                and abs(d / d_label - 1) <= DETECTION_SIZE_TOLERANCE):
            return True
    return False


def copied_detection(label_box: Sequence[float], original_box: Sequence[float] | None,
                     detection_box: Sequence[float]) -> bool:
    """Whether a ball label is a copy of a detection's box: placed in v3d (it differs from the imported label
    ``original_box``, None where the view had none) and equal to ``detection_box``, or to it rounded to the pixel as
    the doubts' fix key places a detector's box (``snap_box``, ``app.services.derivation.doubts``). All (4,)
    ``[x1, y1, x2, y2]`` px of the view's image. Such a label is that detection's own box: the detection cannot
    confirm it (a person's confirmation of the placed box is the one look at the image it has, as for any label)."""
    lb = np.asarray(label_box, dtype=float).reshape(4)
    if original_box is not None and np.array_equal(lb, np.asarray(original_box, dtype=float).reshape(4)):
        return False
    db = np.asarray(detection_box, dtype=float).reshape(4)
    return any(bool(np.allclose(lb, b, rtol=0.0, atol=1e-6)) for b in (db, np.round(db)))


def label_size_ratio(camera: Camera, ball: np.ndarray, label_box: Sequence[float], ball_diameter_m: float
                     ) -> float | None:
    """The label's box diameter ``(w + h) / 2`` over that of the exact silhouette of a sphere of ``ball_diameter_m``
    at ``ball`` (3,) world metres in ``camera`` (:func:`app.geometry.ball.sphere_image_box`); None when the sphere is
    not in front of the camera or either size is not positive."""
    box = sphere_image_box(camera, np.asarray(ball, dtype=float), ball_diameter_m / 2)
    if box is None:
        return None
    lb = np.asarray(label_box, dtype=float).reshape(4)
    d_label = ((lb[2] - lb[0]) + (lb[3] - lb[1])) / 2
    d_ball = ((box[2] - box[0]) + (box[3] - box[1])) / 2
    if not (d_label > 0 and d_ball > 0 and math.isfinite(d_ball)):
        return None
    return float(d_label / d_ball)


def detection_at_ball(camera: Camera, ball: np.ndarray, detections: Sequence[Sequence[float]], ball_diameter_m: float,
                      width_px: float) -> tuple[float, float] | None:
    """The detection nearest where a sphere of ``ball_diameter_m`` at ``ball`` (3,) world metres projects in
    ``camera``: its centre's distance (px at 1920 width, the view's ``width_px`` scaled) from the silhouette's centre
    and its diameter over the silhouette's (:func:`app.geometry.ball.sphere_image_box`); None without a detection or
    with the ball behind the camera. ``detections``: (n, 4) ``[x1, y1, x2, y2]`` px of the view's image."""
    sil = sphere_image_box(camera, np.asarray(ball, dtype=float), ball_diameter_m / 2)
    if sil is None or not detections:
        return None
    centre = (sil[:2] + sil[2:]) / 2
    d_sil = ((sil[2] - sil[0]) + (sil[3] - sil[1])) / 2
    if not (d_sil > 0 and math.isfinite(d_sil)):
        return None
    best: tuple[float, float] | None = None
    for box in detections:
        b = np.asarray(box, dtype=float).reshape(4)
        dist = float(np.linalg.norm((b[:2] + b[2:]) / 2 - centre)) * 1920.0 / width_px
        if best is None or dist < best[0]:
            best = (dist, float(((b[2] - b[0]) + (b[3] - b[1])) / 2 / d_sil))
    return best


def depth_shift_px(camera: Camera, ball: np.ndarray, centres: Sequence[np.ndarray], width_px: float,
                   shift_m: float = 1.0) -> float:
    """How far (px at 1920 width) ``camera`` (an image ``width_px`` wide) sees the ball at ``ball`` (3,) world metres
    move when it moves ``shift_m`` along the ray of each camera centre of ``centres`` ((3,) each, world metres), the
    least over them (inf without centres; 0 where a moved ball falls behind ``camera``). A view whose box is to check a
    ball made from those rays must see a ball wrong by ``shift_m`` along any of them at least this far away."""
    b = np.asarray(ball, dtype=float)
    here, front = camera.project(b.reshape(1, 3))
    if not front[0]:
        return 0.0
    least = math.inf
    for c in centres:
        ray = b - np.asarray(c, dtype=float)
        n = float(np.linalg.norm(ray))
        if not n > 0:
            continue
        moved, ok = camera.project(np.stack([b + shift_m * ray / n, b - shift_m * ray / n]))
        if not ok.all():
            return 0.0
        least = min(least, float(np.min(np.linalg.norm(moved - here[0], axis=1))) * 1920.0 / width_px)
    return least


def _names(names: Sequence[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def ball_evidence(facts: BallFacts) -> tuple[str, list[str]]:
    """The tier of a system's 3D ball and the reasons a reviewer reads (module docstring; the thresholds were chosen
    on the sets ``benchmarks/VOUCH.md`` names, and read on the others).

    Rule:

    * ``none``: no 3D ball;
    * ``doubted``: a label doubt names a view of the ball (``facts.doubted``);
    * ``vouched``, by any of:

      1. **further views**: at least :data:`AGREEING_VIEWS` views every two of which make a kept pair
         (``facts.agreeing``): a wrong label or a replay of another instant would need a second wrong label at the
         same wrong place;
      2. **another view sees it there** (ball sigma at most :data:`VOUCH_MAX_SIGMA_M`): a view outside the kept
         pairs whose detection (``facts.others``) or person-placed label (``facts.labelled_others``) lies within tau
         (``facts.tau_px``, px at 1920 width, the tolerance the pairs are kept by) of where the ball projects, at a
         ball's size there (within :data:`DETECTION_SIZE_TOLERANCE`), and nearer than where a ball 1 m off along a
         ray of the pairs would project (the midpoint, :func:`depth_shift_px`: a near duplicate of one of those
         views sees both at the same place and vouches for nothing): a third ray that meets the ball;
      3. **two views the detector and the players confirm**: every view's label confirmed by a detection
         (:func:`detection_at_label`: the label is on a ball, not on another object nor where none is; a label
         that is a detection's box placed by the fix key is not confirmed by that detection,
         :func:`copied_detection`), the two cameras agreeing on the players both see (the cameras are not off
         along the epipolar line), the pair's error at most :data:`TWO_VIEW_MAX_ERROR_TAU` of tau and the sigma at
         most :data:`TWO_VIEW_MAX_SIGMA_M` (a replay of another instant is the one corruption neither sees: its ray
         meets the other anywhere within tau, a right pair's within a quarter of it);

    * ``unconfirmed``: otherwise (it rests on its views' own agreement).

    Returns:
        ``(tier, reasons)``: one of :data:`TIER_VOUCHED`, :data:`TIER_UNCONFIRMED`, :data:`TIER_DOUBTED`,
        :data:`TIER_NONE`, and short phrases (empty for none).
    """
    if not facts.has_ball:
        return TIER_NONE, []
    if facts.doubted:
        return TIER_DOUBTED, [f"a label doubt names {_names(list(facts.doubted))}"]
    n = len(facts.views)
    loose = facts.sigma_m is not None and facts.sigma_m > VOUCH_MAX_SIGMA_M
    detected = [v.name for v in facts.views if v.detected]
    players = ["the players agree on both cameras"] if facts.players_pairs else []
    if facts.agreeing >= AGREEING_VIEWS:
        return TIER_VOUCHED, [f"{_count(facts.agreeing)} views agree", *_detector(detected), *players]
    seen = [o.name for o in facts.others if _sees(o, facts.tau_px)]
    labelled = [o.name for o in facts.labelled_others if _sees(o, facts.tau_px)]
    if (seen or labelled) and not loose:
        reasons = [f"the detector sees it in {_names(seen)} too"] if seen else []
        reasons += [f"{_names(labelled)}'s label agrees (a view outside its pairs)"] if labelled else []
        return TIER_VOUCHED, [*reasons, *_detector(detected), *players]
    tight = (facts.pair_error_tau is not None and facts.pair_error_tau <= TWO_VIEW_MAX_ERROR_TAU
             and facts.sigma_m is not None and facts.sigma_m <= TWO_VIEW_MAX_SIGMA_M)
    if n >= 2 and len(detected) == n and facts.players_pairs and tight:
        return TIER_VOUCHED, [*_detector(detected), *players, "its rays meet well within tau"]
    reasons = ["only two views: nothing else checks it" if n <= 2 else "its views do not all agree: nothing else "
               "checks it"]
    reasons += _detector(detected) + players
    if loose:
        reasons.append(f"its sigma is {facts.sigma_m:.2f} m")
    return TIER_UNCONFIRMED, reasons


def _sees(other: OtherView, tau_px: float) -> bool:
    """Whether another view's box lies where the ball projects, at a ball's size there: within ``tau_px`` (px at 1920
    width) and nearer than half of ``depth_1920``, i.e. nearer where the ball projects than where a ball 1 m off along
    a ray of its pairs would (the midpoint between the two; a near duplicate of one of the ball's views, which sees
    both at the same place, never passes)."""
    return (other.distance_1920 <= min(tau_px, other.depth_1920 / 2)
            and abs(other.size_ratio - 1) <= DETECTION_SIZE_TOLERANCE)


def _detector(names: Sequence[str]) -> list[str]:
    return [f"the detector confirms {_names(list(names))}"] if names else []


def _count(n: int) -> str:
    return {2: "two", 3: "three", 4: "four", 5: "five"}.get(n, str(n))
