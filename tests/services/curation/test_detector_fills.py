"""The detector's check's fills where no labelled views agree on a ball, on games of the shared detector set imported
as a user would (its labels a third removed, its true ball and centres in the truth file): a lone ray's pairing whose
ball lies on the grass, placed to within a metre, fills its view; a view whose detector missed the ball a pairing
places gets that ball's sphere box. Every box the check suggests there is right (within max(3 px, d/2))."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

from app.db.models import Doubt
from tests.services.curation.test_detected_by_players import import_detector_game

SET = "dev-large"
FENWICK = Path("synth_league_a/2031-2032/2031-08-01 - 14-00 Glenrock 0 - 3 Fenwick")


def _fills(shared_dir: Path, tmp_path: Path, factory: Any, game: Path) -> tuple[dict[str, Any], dict[str, tuple]]:
    """The game imported with its predictions: image -> its label doubts' (kind, code, box), and image -> (true
    centre, the scorer's tolerance)."""
    with factory("game") as session:
        frames, centres = import_detector_game(session, shared_dir, tmp_path, SET, game)
        doubts = session.scalars(sa.select(Doubt).where(Doubt.frame_id.in_(frames), Doubt.accuses_label.is_(True)))
        fills: dict[str, Any] = {}
        for d in doubts:
            fills.setdefault(frames[d.frame_id].name, []).append(
                (d.kind, d.evidence["code"], (d.suggestion or {}).get("box") or d.evidence.get("box")))
    return fills, centres


def _right(box: list[float], centre: tuple) -> bool:
    (cx, cy), tol = centre
    return math.hypot((box[0] + box[2]) / 2 - cx, (box[1] + box[3]) / 2 - cy) <= tol


def _the_fill(fills: dict[str, Any], image: str, kind: str, code: str) -> list[float]:
    """The one box of ``image``'s doubts of that kind and code (a ValueError where there is none or several)."""
    (box,) = [b for k, c, b in fills[image] if (k, c) == (kind, code)]
    return box


def _each_right(fills: dict[str, Any], centres: dict[str, tuple], kinds: tuple[str, ...]) -> None:
    """Every box of those doubt kinds on an unlabelled view whose truth is known lies at the true ball."""
    for image, found in fills.items():
        for kind, code, box in found:
            if kind in kinds and box is not None and image in centres:
                assert _right(box, centres[image]), (image, kind, code)


def test_a_lone_rays_pairings_on_the_grass_placed_to_a_metre_fill_their_views(shared_dir, tmp_path,
                                                                             fresh_session_factory):
    # two systems of this game whose one labelled ray and one detection put the ball on the grass with a spread of
    # 0.5-1 m (benchmarks/DETECTOR.md, branch fill4): both views filled, both right
    fills, centres = _fills(shared_dir, tmp_path, fresh_session_factory,
                            Path("synth_league_b/2031-2032/2031-09-08 - 16-00 Harlow 0 - 3 Marden"))
    for image in ("4.png", "21.png"):
        box = _the_fill(fills, image, "ball_detected", "one_ray")
        assert _right(box, centres[image]), image
    _each_right(fills, centres, ("ball_detected", "ball_missing"))


def test_a_view_whose_detector_missed_the_ball_a_pairing_places_gets_its_box(shared_dir, tmp_path,
                                                                            fresh_session_factory):
    fills, centres = _fills(shared_dir, tmp_path, fresh_session_factory,
                            Path("synth_league_b/2031-2032/2031-12-01 - 14-00 Glenrock 2 - 3 Oakhurst"))
    box = _the_fill(fills, "7_1.png", "ball_missing", "pairing")
    assert _right(box, centres["7_1.png"])
    assert [kind for kind, _, _ in fills["7_1.png"]].count("ball_missing") == 1  # one suggestion for the view
    for image, found in fills.items():
        for _, code, box in found:
            if code == "pairing":
                assert image in centres and _right(box, centres[image]), image


def test_unsure_cameras_take_part_weighted_by_their_uncertainty(shared_dir, tmp_path, fresh_session_factory):
    # two systems of this game (benchmarks/DETECTOR.md, branch vote5): in 17.png the one labelled ray's camera is
    # unsure beyond tau (sigma 27 px) and its pairing with the view's detection is placed by the spread that sigma
    # leaves; in 14.png the one ray is a half vote (a camera its players placed, sigma 1 px) with two boxes near it,
    # of which one alone lies within its cameras' and the detector's uncertainty of the ray: both filled, both right
    fills, centres = _fills(shared_dir, tmp_path, fresh_session_factory, FENWICK)
    for image in ("17.png", "14_1.png"):
        box = _the_fill(fills, image, "ball_detected", "one_ray")
        assert _right(box, centres[image]), image
    _each_right(fills, centres, ("ball_detected",))


def test_a_view_whose_camera_takes_no_part_in_the_votes_is_not_filled_where_its_box_would_make_the_ball(
        shared_dir, tmp_path, fresh_session_factory):
    # 5.png: three line classes, a camera unsure to 33 px (no vote in the doubts), one labelled ray (sigma 5 px) and
    # nothing else placed in its system. Its one box near that ray within both sigmas is right, and the rule by class
    # filled it (weak_view: the box made no ball there); the ball judged by evidence (the default) lets that camera
    # take part weighed by its sigma, so the box would make the ball with the lone ray alone, what a weak fill may
    # never do (on a made detector set such a fill made a ball 1.02 m off: benchmarks/VOUCH.md, 2026-11-29 later)
    fills, centres = _fills(shared_dir, tmp_path, fresh_session_factory,
                            Path("synth_league_c/2031-2032/2031-10-15 - 18-00 Glenrock 0 - 1 Arden"))
    assert "5.png" in centres
    assert not [code for kind, code, _ in fills.get("5.png", []) if kind == "ball_detected"]


def _detected_doubts(session: Any, shared_dir: Path, tmp_path: Path) -> tuple[dict[int, Any], list[Doubt]]:
    """Glenrock 0 - 3 Fenwick of the set imported with its predictions: its frames by id and its ``ball_detected``
    doubts in id order."""
    frames, _ = import_detector_game(session, shared_dir, tmp_path, SET, FENWICK)
    detected = session.scalars(sa.select(Doubt).where(Doubt.frame_id.in_(frames), Doubt.kind == "ball_detected")
                               .order_by(Doubt.id)).all()
    return frames, list(detected)


def test_a_detectors_box_says_the_error_its_view_shows_once_confirmed(shared_dir, tmp_path, fresh_session_factory):
    # every system of this game with a detector's box to place: the doubt's number is the one the view shows once a
    # person confirms the box (before, the check's number, against a ball refitted through the box itself, read
    # 0.9 px on 21_1.png where the view then showed 4.5 px)
    from app.core.config import Settings
    from app.db.models import Frame
    from app.services.curation.editing import update_ball_label

    settings = Settings(calibration_workers=1)
    with fresh_session_factory("game") as session:
        frames, detected = _detected_doubts(session, shared_dir, tmp_path)
        said = {}
        for d in detected:  # one per system: confirming a box changes what its system's other doubts say
            if d.suggestion is None:  # no fix key (without_unbacked_fixes): nothing placed to confirm
                continue
            said.setdefault(frames[d.frame_id].system_id, (d.frame_id, d.suggestion["box"], d.evidence))
        assert len(said) >= 8 and any("from the 3D ball" in d.message for d in detected)
        for frame_id, box, evidence in said.values():
            update_ball_label(session, frame_id, box=box, settings=settings)
            session.commit()
            rep = session.get(Frame, frame_id).reprojection
            shown = None if rep is None else rep.error_px
            if evidence["confirmed_error_px"] is None:
                assert shown is None, frame_id
            else:
                assert shown == pytest.approx(evidence["confirmed_error_px"], abs=0.006), frame_id


def test_a_box_the_key_placed_from_a_detection_is_not_confirmed_by_that_detection(shared_dir, tmp_path,
                                                                                 fresh_session_factory):
    # each system of this game with a detector's box to place, placed as the key places it (rounded to the pixel)
    # and confirmed: where the ball then stands on that view, the evidence never says the detector confirms it (the
    # detection is the label's own box; app.geometry.ball_evidence.copied_detection), while other views' labels of a
    # person's are still confirmed by theirs
    import re

    from app.core.config import Settings
    from app.db.models import Frame, System
    from app.services.curation.editing import update_ball_label

    settings = Settings(calibration_workers=1)
    with fresh_session_factory("game") as session:
        frames, detected = _detected_doubts(session, shared_dir, tmp_path)
        placed: dict[int, tuple[int, list[float]]] = {}
        for d in detected:
            if d.suggestion is not None:
                placed.setdefault(frames[d.frame_id].system_id, (d.frame_id, d.suggestion["box"]))
        read, others = 0, 0
        for system_id, (frame_id, box) in placed.items():
            update_ball_label(session, frame_id, box=[float(round(x)) for x in box], settings=settings)
            session.commit()
            system = session.get(System, system_id)
            name = f"V{[f.id for f in system.frames].index(frame_id) + 1}"
            said = [r for r in system.ball_evidence_reasons if r.startswith("the detector confirms")]
            assert session.get(Frame, frame_id).ball_label.box == [float(round(x)) for x in box]
            read += system.ball_evidence.value != "none"
            others += bool(said)
            assert not any(re.search(rf"\b{name}\b", r) for r in said), (system.name, name, said)
        assert read >= 5 and others >= 1, (read, others)
