"""The words of doubts and mirror verdicts: one sentence per code, composed from the numbers the geometry returns.

The geometry (``app.geometry.doubts``, ``app.geometry.mirror``) returns codes and numbers only; this module is
the one place where they become sentences for people: the stored ``Doubt.message`` (the API's ``message``,
the system page, ``v3d doubts --json``) and the ``sentence`` of a calibration's ``mirror_evidence``. Views are
named by their image names (``names``: view id -> name).
"""
from __future__ import annotations

import math
from typing import Any, Callable, Mapping

from app.geometry.doubts import Doubt as DoubtFinding
from app.geometry.mirror import AMBIGUOUS, DIFFERENT, SAME, VERDICT_AS_LABELLED, VERDICT_MIRRORED
from app.geometry.pair_error import REFERENCE_WIDTH_PX

Names = Mapping[Any, str]


def _num(x: Any, nd: int = 0, unknown: str = "an unknown number of") -> str:
    return unknown if not isinstance(x, (int, float)) or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


def _list(ids: Any, names: Names) -> str:
    return ", ".join(names.get(i, str(i)) for i in (ids or []))


def doubt_message(d: DoubtFinding, names: Names) -> str:
    """One sentence with the numbers of the doubt ``d`` (its ``kind``, ``code`` and ``evidence``).

    Args:
        d: a doubt of ``app.geometry.doubts.judge_system`` (or of a kind's own judge, e.g. ISSIA's trajectory).
        names: view id -> image name.

    Raises:
        KeyError: a kind/code pair this module has no sentence for (a new code must get its words here).
    """
    ev = d.evidence or {}
    said = _WRITERS[(d.kind, d.code)](ev, names.get(d.view_id, str(d.view_id)), names)
    return said + _no_key(ev, names)


def _no_key(ev, n) -> str:
    """Why a placed box gets no fix key (``evidence["no_key"]``,
    ``app.services.derivation.doubts.without_unbacked_fixes``); "" when it has one."""
    if ev.get("no_key") == "agreeing":
        return (f" No fix key: the 3D ball keeps no ball from the labels of {_list(ev.get('agreeing_views'), n)} "
                "(its rule refuses their agreement), so a box placed where they agree would make a ball nothing else "
                "backs; place the label by eye where the ball is.")
    if ev.get("no_key") == "one_ray":
        ray = _list((ev.get("agreeing_views") or [])[:1], n) or "the labelled view"
        ball = ev.get("ball3d") or [None, None, None]
        up = _num(-ball[2] if isinstance(ball[2], (int, float)) else None, 1, "an unknown number of")
        return (f" No fix key: only this box says where along {ray}'s ray the ball is ({up} m above the grass, where "
                "no third view sees it), and a false box on that ray at a ball's size would say the same; place the "
                "label by eye where the ball is.")
    if ev.get("no_key") == "one_view":
        return (f" No fix key: confirmed beside {_list(ev.get('agreeing_views'), n)}, this box and the others of its "
                "pairing would not make a ball every one of these views agrees on by the 3D ball's rule (it finds two "
                "of their rays disagree: beyond tau, their joint sigma or their players), so nothing would check "
                "where the ball they make lies; place the label by eye where the ball is.")
    if ev.get("no_key") == "detections":
        return (" No fix key: no label a person placed takes part, and boxes placed from detections alone would make "
                "a 3D ball of the detector's boxes alone; place the label by eye where the ball is.")
    return ""


def _refused(ev, v, n):
    return (f"{v} has no camera ({ev.get('reason') or 'no calibration'}), so its labels cannot be checked against "
            "the other views.")


def _below(ev, v, n):
    jac = ev.get("jac")
    return (f"{v} is calibrated with JaC@0.5 % {'unknown' if jac is None else f'{jac:.3f}'}, below admission, so its "
            "labels are checked only as far as its calibration's uncertainty allows.")


def _rig(ev, v, n):
    return f"{v} was calibrated at a camera position of the game's rig (its lines alone did not fix the camera)."


def _few(ev, v, n):
    return (f"{v} has {ev.get('line_classes')} field-line classes (fewer than {ev.get('min_line_classes')}), "
            "too few to fix its camera reliably.")


_NO_FIX = {
    "as_labelled_meets": "as labelled its ball ray meets another view's, mirrored it would not",
    "no_ray_confirms": "no other view's ball confirms the mirrored camera",
    "one_view_cannot_tell": "a single other view's ray meets it only mirrored, but one other view cannot tell which "
                            "of the two is mirrored, and the game's rig does not place the mirrored camera at a known "
                            "camera; a third view of the ball would tell",
    "as_labelled_fits": "as labelled its ball label is closer ({as_} px at 1920 width) to the ball the other views "
                        "agree on than mirrored ({mi} px), so the mirrored calibration and the ball do not agree "
                        "better",
    "mirrored_misses": "mirrored, its ball label would still be {mi} px (at 1920 width) from the ball the other views "
                       "agree on",
}


def _mirror(ev, v, n, suspected: bool = False):
    if suspected:
        why = (f"no other view's ball ray meets its ray only as labelled, and mirrored its camera stands "
               f"{_num(ev.get('rig_distance_mirrored_m'), 2)} m from a known camera of the game against "
               f"{_num(ev.get('rig_distance_m'), 1)} m as labelled")
    elif ev.get("refit"):
        r = ev["refit"]
        pos = ", ".join(_num(x) for x in r.get("position_m") or [])
        why = (f"as labelled they calibrate no camera on the main camera's side; mirrored they do, at ({pos}) m, "
               f"within {_num(r.get('rms_px'), 1)} px RMS" if r.get("source") == "lines" else
               f"as labelled they fit no camera; mirrored they fit the game's camera position ({pos}) m within "
               f"{_num(r.get('rms_px'), 1)} px RMS")
    else:
        margin = ev.get("margin")
        why = "the mirror evidence flags it" + (f" (margin {margin:.1f})" if isinstance(margin, (int, float)) else "")
    if ev.get("fix_agrees"):
        if ev.get("error_mirrored_px_1920") is not None:
            why += (f"; mirrored, its ball label is {_num(ev['error_mirrored_px_1920'])} px (at 1920 width) from the "
                    f"ball the other views agree on, against {_num(ev.get('error_as_labelled_px_1920'), 0, 'more')} px "
                    "as labelled")
        return f"{v}'s field lines look labelled left for right: {why}."
    no_fix = _NO_FIX.get(ev.get("no_fix"), "nothing confirms the mirrored camera").format(
        as_=_num(ev.get("error_as_labelled_px_1920")),
        mi=_num(ev.get("error_mirrored_px_1920"), 0, "an unknown number of"))
    return f"{v}'s field lines look labelled left for right: {why}; no fix is offered: {no_fix}."


def _off(ev, v, n):
    sig = ev.get("calibration_sigma_px_1920") or 0
    tol = f"tolerance {_num(ev.get('tau_px'))} px" + (f", its calibration's own uncertainty {_num(sig)} px"
                                                      if sig > (ev.get("tau_px") or 0) - 1e-9 and sig else "")
    return (f"{v}'s ball label is {_num(ev.get('error_px_1920'))} px (at 1920 width) away from the ball that "
            f"{_list(ev.get('agreeing_views'), n)} agree on ({tol}).")


def _behind(ev, v, n):
    return (f"{v}'s ball label is behind the camera seen from the ball that {_list(ev.get('agreeing_views'), n)} agree "
            f"on (tolerance {_num(ev.get('tau_px'))} px).")


def _trajectory(ev, v, n):
    res = ev.get("residual_px_1920")
    far = "an unknown distance" if res is None else f"{res:.0f} px (at 1920 width)"
    return (f"{v}'s ball label at frame {ev.get('frame_index')} is {far} from where the sequence's ball trajectory "
            f"projects ({ev.get('source') or 'no'} position); it breaks the trajectory.")


def _missing(ev, v, n):
    p = ev.get("projected_px") or [math.nan, math.nan]
    said = (f"{v} has no ball label, but the ball that {_list(ev.get('agreeing_views'), n)} agree on projects inside "
            f"it at ({_num(p[0])}, {_num(p[1])}) px")
    if ev.get("ball_loose"):
        return (f"{said}; they fix that ball too loosely for {v} (it may lie {_num(ev.get('ball_sigma_px'))} px from "
                "there, more than the ball's size), so no box is suggested: place the label where the ball is.")
    if ev.get("detection_size_disagrees"):
        return (f"{said}; a detection there is not a ball's size at that depth (the camera's scale or the box is "
                "off), so no box is suggested: place the label where the ball is.")
    return f"{said}."


def _missing_epipolar(ev, v, n):
    other = _list(ev.get("agreeing_views"), n)
    g = ev.get("grass_px") or [math.nan, math.nan]
    frac = ev.get("inside_fraction")
    where = ("if it is on the grass, as its box size says" if ev.get("placed") == "grass"
             else "at the depth its box size gives")
    return (f"{v} has no ball label, but the ball of {other} lies on that view's ray, inside {v} at ({_num(g[0])}, "
            f"{_num(g[1])}) px {where}, and "
            f"{'wholly' if frac == 1 else f'{_num(100 * frac if frac is not None else None)} % of it'} inside {v} over "
            f"the depths its box size allows (a chance of {_num(100 * (ev.get('inside_chance') or 0))} % that the ball "
            f"is inside) (the segment drawn, {_num(ev.get('segment_length_px_1920'))} px at 1920 width); its height is "
            f"unknown with only {other} labelled, so no box is suggested: place the label on the segment.")


def _missing_epipolar_box(ev, v, n):
    other = _list(ev.get("agreeing_views"), n)
    p = ev.get("projected_px") or [math.nan, math.nan]
    return (f"{v} has no ball label, but the ball of {other} lies on that view's ray, whose stretch over the depths "
            f"its box size allows lies inside {v} and is short ({_num(ev.get('segment_length_px_1920'))} px at 1920 "
            f"width): the box suggested at ({_num(p[0])}, {_num(p[1])}) px, on the grass, is a guess along it, not "
            "evidence, until a person places it.")


def _missing_pairing(ev, v, n):
    p = ev.get("projected_px") or [math.nan, math.nan]
    filled = _list(ev.get("filled_views"), n)
    return (f"{v} has no ball label and its detector shows nothing there, but the ball that "
            f"{_list(ev.get('agreeing_views'), n)} place (with the detections suggested in {filled}) projects inside "
            f"it at ({_num(p[0])}, {_num(p[1])}) px, surely enough that its box lies on the ball: the box agrees with "
            "that ball by construction, no evidence of its own, until a person places it.")


#: Which rule placed a detector's box (``ball_detected`` code), in the words of its sentence.
_DETECTED_RULE = {
    "consensus": "",
    "one_view": " (with only one view labelled, two views' detections had to agree with it and each other)",
    "one_ray": " (one labelled view and this detection: their rays meet in the play volume, at a ball's size in "
               "both boxes, and no third view misses it)",
    "detections_agree": " (no labelled view takes part: the detections of these views meet at one ball of a ball's "
                        "size, and no third view misses it)",
    "weak_ray": " (a label whose camera takes no part in the votes and this detection, the only one near its ray: "
                "they meet in the play volume at a ball's size, no third view misses it, and the box cannot make a 3D "
                "ball with that ray)",
    "weak_view": " (this view's camera takes no part in the votes: the ball the others place, or the one labelled "
                 "view's ray, passes here within its uncertainty, and no other detection lies near; the box cannot "
                 "make a 3D ball)",
}


def _once_confirmed(ev) -> str:
    """What a label confirmed as it is will show (``confirmed_error_px``, px of the view, and its scaled value at
    the pair rule's reference width): the view's own "Ball off by" then, from the same computation; "" when unknown
    (a doubt stored before the number was kept)."""
    if "confirmed_error_px" not in ev:
        return ""
    px, scaled = ev.get("confirmed_error_px"), ev.get("confirmed_error_scaled_px")
    if not isinstance(px, (int, float)):
        return "; confirmed, it makes no 3D ball yet"
    at = f" ({scaled:.2f} px at {REFERENCE_WIDTH_PX:g} width)" if isinstance(scaled, (int, float)) and abs(
        scaled - px) > 1e-6 else ""
    return f"; confirmed, it lies {px:.2f} px{at} from the 3D ball"


def _detected(ev, v, n, code: str = "consensus"):
    others = _list(ev.get("agreeing_views"), n)
    rivals = ev.get("candidates_passed") or 1
    margin = (f"; {rivals - 1} other candidate(s) also fit, {_num(ev.get('margin_px_1920'), 1)} px worse"
              if rivals > 1 and ev.get("margin_px_1920") is not None else "")
    where = "where the detections of" if code == "detections_agree" else "where"
    # one number for how far the box lies from the ball: the view's own once it is confirmed; the check's (against a
    # ball refitted through the box itself, which reads smaller) only where that one is unknown
    near = (f"{where} {others} put it" if "confirmed_error_px" in ev
            else f"{_num(ev.get('error_px_1920'), 1)} px (at 1920 width) from {where} {others} put it")
    return (f"A detector ({ev.get('detector')}, score {_num(ev.get('score'), 2)}) found the ball in {v} {near}, at "
            f"{_num(100 * (ev.get('size_ratio') or math.nan))} % of a ball's size there{_DETECTED_RULE[code]}{margin}; "
            f"{_placing(ev)}.")


def _placing(ev) -> str:
    """How a detector's box becomes the label: its fix key (s, then a person's confirmation), or, where the box gets
    no key (``evidence["no_key"]``, said after the sentence), where the box lies for a person to judge by eye."""
    if not ev.get("no_key"):
        return f"s places its box, to be confirmed{_once_confirmed(ev)}"
    box = ev.get("box")
    if not box or len(box) != 4:
        return "its box is not placed by a key"
    return f"its box lies at x {_num(box[0])}-{_num(box[2])}, y {_num(box[1])}-{_num(box[3])} px"


def _detection_off(ev, v, n):
    return (f"A detector ({ev.get('detector')}, score {_num(ev.get('score'), 2)}) found a ball in {v} "
            f"{_num(ev.get('error_px_1920'), 1)} px (at 1920 width) from where {_list(ev.get('agreeing_views'), n)} "
            f"put it, {_num(ev.get('label_distance_px_1920'))} px from {v}'s label: evidence that the label is off, "
            "not a verdict.")


def _disagree(ev, v, n):
    names = _list(ev.get("views"), n)
    best = ev.get("best_pair_error_px_1920")
    miss = ("their rays diverge or meet where no ball can be" if best is None
            else f"best pair misses by {best:.0f} px at 1920 width")
    decide = ("a third view of the ball" if ev.get("third_view") else "another view of the ball") + \
        " or a check of the replays' timing would tell which label is wrong"
    return f"The ball labels of {names} cannot all be right ({miss}, tolerance {_num(ev.get('tau_px'))} px); {decide}."


def _disagree_epipolar(ev, v, n):
    names = _list(ev.get("views"), n)
    decide = ("a third view of the ball" if ev.get("third_view") else "another view of the ball") + \
        " or a check of the replays' timing would tell which label is wrong"
    return (f"The ball labels of {names} cannot all be right: their cameras are too close in direction to triangulate, "
            f"but each label lies at least {_num(ev.get('best_pair_error_px_1920'))} px (at 1920 width) from the other "
            f"view's ray across the play volume (tolerance {_num(ev.get('tau_px'))} px); {decide}.")


def _disagree_lone_pair(ev, v, n):
    names = _list(ev.get("views"), n)
    return (f"The ball labels of {names} agree only at the edge of tolerance: their rays miss by "
            f"{_num(ev.get('best_pair_error_px_1920'))} px at 1920 width, more than a right pair's "
            f"{_num(ev.get('edge_px'))} px (of {_num(ev.get('tau_px'))}) and more than their cameras' "
            f"{_num(ev.get('joint_sigma_px_1920'))} px of uncertainty; two views of different instants cross so. "
            "A third view of the ball or a check of the replays' timing would tell which label is wrong.")


def _near_dup(ev, v, n):
    return (f"{v} sees the ball from nearly the same place as {n.get(ev.get('other_view'), ev.get('other_view'))} "
            f"(their cameras are {ev.get('angle_deg', 0):.2f} deg apart seen from the ball, "
            f"{ev.get('baseline_m', 0):.1f} m apart), so it adds no depth.")


_WRITERS: dict[tuple[str, str], Callable[[dict, str, Names], str]] = {
    ("calibration_refused", "refused"): _refused,
    ("below_admission", "below_admission"): _below,
    ("rig_assisted", "rig_assisted"): _rig,
    ("few_lines", "few_lines"): _few,
    ("suggested_label", "unconfirmed"): lambda ev, v, n: (
        f"{v}'s ball label was suggested by a doubt and no person has placed it yet: it makes no 3D ball and confirms "
        f"nothing until someone moves or confirms it on the image{_once_confirmed(ev)}."),
    ("mirrored_labels", "flagged"): _mirror,
    ("mirrored_labels", "suspected"): lambda ev, v, n: _mirror(ev, v, n, suspected=True),
    ("ball_off_consensus", "off_consensus"): _off,
    ("ball_off_consensus", "behind_camera"): _behind,
    ("ball_off_consensus", "trajectory"): _trajectory,
    ("ball_missing", "consensus"): _missing,
    ("ball_missing", "epipolar"): _missing_epipolar,
    ("ball_missing", "epipolar_box"): _missing_epipolar_box,
    ("ball_missing", "pairing"): _missing_pairing,
    ("views_disagree", "no_agreement"): _disagree,
    ("views_disagree", "ambiguous"): _disagree,
    ("views_disagree", "epipolar"): _disagree_epipolar,
    ("views_disagree", "lone_pair"): _disagree_lone_pair,
    ("near_duplicate_view", "near_duplicate"): _near_dup,
    **{("ball_detected", code): (lambda c: lambda ev, v, n: _detected(ev, v, n, c))(code) for code in _DETECTED_RULE},
    ("detection_off_label", "agrees_with_others"): _detection_off,
}


def _miss(error: float | None, other: str) -> str:
    """How a line of sight to the ball misses another (``other`` names it): by how many px, or crossing it only
    behind a camera (where no ball can be; the geometry's "rays meet only behind a camera")."""
    if error is None:
        return f"crosses {other} only behind a camera, where no ball can be"
    return f"misses {other} by {error:.0f} px"


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.0f}"


def mirror_sentence(verdict: Mapping[str, Any], names: Names, flagged: set | frozenset = frozenset()) -> str:
    """The sentence of one view's mirror verdict (``MirrorVerdict.as_dict()``): the evidence for mirroring first,
    then the evidence against it ("against: ..."); a pair with a view that is itself flagged (``flagged``: ids)
    says so. A verdict of ``app.geometry.mirror.mirrored_fit_at_rig`` (``refit``) states the fit; one of a camera
    the players placed (``refit`` of source ``players``, ``app.services.calibration.players.players_mirror_evidence``)
    states where they placed it."""
    refit = verdict.get("refit")
    if refit and refit.get("source") == "players":
        pos = ", ".join(_num(x) for x in refit.get("position_m") or [])
        return (f"Labels probably mirrored: the camera its {refit.get('players')} players place at ({pos}) m meets its "
                f"lines only mirrored (within {_num(refit.get('line_px'), 1)} px); as labelled they fit no camera "
                "with the players.")
    if refit and refit.get("source") == "lines":
        pos = ", ".join(_num(x) for x in refit.get("position_m") or [])
        return (f"Labels probably mirrored: as labelled they calibrate no camera on the main camera's side; mirrored, "
                f"they calibrate with the camera at ({pos}) m within {_num(refit.get('rms_px'), 1)} px RMS.")
    if refit:
        pos = ", ".join(_num(x) for x in refit.get("position_m") or [])
        y = verdict.get("camera_y_m")
        side = (f"; as labelled the camera would stand at y = {y:+.0f} m, beyond the far side line for a main camera"
                if verdict.get("side_vote") == 1 and isinstance(y, (int, float)) else "")
        return ("Labels probably mirrored: as labelled they fit no camera position of the game; mirrored, they fit "
                f"the position ({pos}) m within {_num(refit.get('rms_px'), 1)} px RMS{side}.")
    pro: list[str] = []  # evidence that this view's labels are mirrored
    con: list[str] = []  # evidence that they are right
    y = float(verdict.get("camera_y_m") or 0.0)
    side_vote, rig = verdict.get("side_vote"), verdict.get("rig_vote")
    d, dm = verdict.get("rig_distance_m"), verdict.get("rig_distance_mirrored_m")
    if side_vote == 1:
        pro.append(f"the camera stands at y = {y:+.0f} m, beyond the far side line for a main camera "
                   f"(mirrored: y = {-y:+.0f} m)")
    elif side_vote == -1:
        con.append(f"the camera stands at y = {y:+.0f} m, on the main camera's side")
    if rig == 1:
        pro.append(f"its mirror image is {_num(dm, 1)} m from a camera position of the game, the camera "
                   f"itself {_num(d)} m from the nearest one")
    elif rig == -1:
        con.append(f"the camera is {_num(d, 1)} m from a camera position of the game, its mirror image "
                   f"{_num(dm)} m from the nearest one")
    for p in verdict.get("pairs") or []:
        other = names.get(p.get("other"), str(p.get("other")))
        note = f" (view {other} is itself flagged)" if p.get("other") in flagged else ""
        rel = p.get("relation")
        if rel == DIFFERENT:
            (con if note else pro).append(
                f"as labelled its line of sight to the ball "
                f"{_miss(p.get('error_as_labelled_px'), f'that of view {other}')}, "
                f"mirrored it meets it within {_fmt(p.get('error_mirrored_px'))} px{note}")
        elif rel == SAME:
            (pro if note else con).append(
                f"as labelled its line of sight to the ball meets that of view {other} within "
                f"{_fmt(p.get('error_as_labelled_px'))} px, "
                f"mirrored it {_miss(p.get('error_mirrored_px'), 'it')}{note}")
        elif rel == AMBIGUOUS:
            con.append(f"with view {other} the ball is too near the centre spot to tell")
    v = verdict.get("verdict")
    heads: dict[Any, str] = {VERDICT_MIRRORED: "Labels probably mirrored",
                             VERDICT_AS_LABELLED: "Labels as given agree with the evidence"}
    head = heads.get(v, "Mirroring undecided")
    first, second = (con, pro) if v == VERDICT_AS_LABELLED else (pro, con)
    if not first and not second:
        return head + ": no evidence either way."
    text = head + ": " + ("; ".join(first) if first else "nothing for it")
    return text + ("; against: " + "; ".join(second) if second else "") + "."


def with_sentence(verdict: Mapping[str, Any], names: Names, flagged: set | frozenset = frozenset()) -> dict[str, Any]:
    """``verdict`` (a ``MirrorVerdict.as_dict()``) with its ``sentence`` (:func:`mirror_sentence`): what a
    calibration's ``mirror_evidence`` stores."""
    return {**verdict, "sentence": mirror_sentence(verdict, names, flagged)}
