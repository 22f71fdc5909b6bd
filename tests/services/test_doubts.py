"""Doubts in the service (``app.services.curation.doubts``): stored with every recomputation in the edit's
transaction, counted per system, mapped from the settings, and left untouched by an edit that fails."""
from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np
import pytest
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import System
from app.geometry.ball import sphere_image_box
from app.geometry.doubts import LABEL_KINDS, DoubtSettings
from app.services.curation import doubts as doubt_service
from app.services.curation import editing
from app.services.curation.doubts import doubt_settings

from tests.api.factories import BALL, make_game, make_system


def _stored(session: Session, system_id: int) -> System:
    session.expire_all()
    return session.get(System, system_id)


def _counts_match(system: System) -> None:
    assert system.doubt_counts == dict(Counter(d.kind for d in system.doubts))
    assert system.label_doubts == sum(d.kind in LABEL_KINDS for d in system.doubts)
    assert all(d.accuses_label == (d.kind in LABEL_KINDS) for d in system.doubts)


def test_settings_map_onto_the_judge_field_by_field() -> None:
    settings = Settings(triangulation_tau_px=17.0)
    mapped = doubt_settings(settings)
    for f in dataclasses.fields(DoubtSettings):
        if f"doubt_{f.name}" in Settings.model_fields:
            assert getattr(mapped, f.name) == getattr(settings, f"doubt_{f.name}"), f.name
        elif f.name in Settings.model_fields:
            assert getattr(mapped, f.name) == getattr(settings, f.name), f.name
    if "triangulation_tau_px" in {f.name for f in dataclasses.fields(DoubtSettings)}:
        assert mapped.triangulation_tau_px == 17.0


def test_a_clean_system_has_no_label_doubt(db_session: Session, db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session))
    system = _stored(db_session, scene.system_id)
    assert system.label_doubts == 0
    _counts_match(system)


def test_removing_a_label_stores_a_missing_ball_doubt_with_the_true_box(db_session: Session,
                                                                     db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session))
    missing_id = scene.frame_ids[2]
    editing.update_ball_label(db_session, missing_id, settings=db_settings)  # the ball is "not visible"
    system = _stored(db_session, scene.system_id)
    _counts_match(system)
    (doubt,) = [d for d in system.doubts if d.kind == "ball_missing"]
    assert doubt.frame_id == missing_id and doubt.suggestion["action"] == "snap_box"
    truth = sphere_image_box(scene.cameras[2], BALL, db_settings.ball_diameter_m / 2)
    np.testing.assert_allclose(doubt.suggestion["box"], truth, atol=1.0)

    # snapping to the suggestion (the fix) clears the doubt, in the edit's own transaction
    editing.update_ball_label(db_session, missing_id, box=doubt.suggestion["box"], settings=db_settings)
    system = _stored(db_session, scene.system_id)
    assert not [d for d in system.doubts if d.kind == "ball_missing"]
    _counts_match(system)


def test_a_failing_judge_leaves_the_label_and_the_doubts_unchanged(db_session: Session, db_settings: Settings,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session), shift_px=(0.0, 0.0, 80.0))
    before = [(d.kind, d.frame_id, d.message) for d in _stored(db_session, scene.system_id).doubts]
    box_before = _stored(db_session, scene.system_id).frames[2].ball_label.box

    def broken(*args, **kwargs):
        raise RuntimeError("judge exploded")

    monkeypatch.setattr(doubt_service, "judge_system", broken)
    with pytest.raises(RuntimeError):
        editing.update_ball_label(db_session, scene.frame_ids[2], box=[10.0, 10.0, 20.0, 20.0], settings=db_settings)
    system = _stored(db_session, scene.system_id)
    assert [(d.kind, d.frame_id, d.message) for d in system.doubts] == before
    assert system.frames[2].ball_label.box == box_before


def test_exclusion_is_stored_reversible_and_leaves_the_view_out(db_session: Session, db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session), shift_px=(0.0, 0.0, 80.0))
    fid = scene.frame_ids[2]
    editing.set_view_excluded(db_session, fid, True, settings=db_settings)
    system = _stored(db_session, scene.system_id)
    frame = next(f for f in system.frames if f.id == fid)
    assert frame.review.excluded is True and frame.review.status.value == "pending"
    assert all(fid not in (p.frame_a_id, p.frame_b_id) for p in system.triangulation.pairs)
    np.testing.assert_allclose(system.triangulation.ball3d, BALL, atol=1e-6)  # the two good views
    assert not [d for d in system.doubts if d.frame_id == fid and d.accuses_label]
    editing.set_view_excluded(db_session, fid, False, settings=db_settings)
    system = _stored(db_session, scene.system_id)
    assert len(system.triangulation.pairs) == 3
    assert next(f for f in system.frames if f.id == fid).review.excluded is False
    with pytest.raises(editing.InvalidInputError):
        editing.set_view_excluded(db_session, fid, "yes", settings=db_settings)  # type: ignore[arg-type]


def test_systems_stored_by_an_older_version_are_recomputed_once(db_session: Session, db_settings: Settings) -> None:
    """After a schema upgrade the stored doubts and queue figures are empty (``derived_version`` 0):
    ``refresh_stale_systems`` recomputes exactly those systems, and then nothing."""
    from app.services.curation.recompute import DERIVED_VERSION, refresh_stale_systems

    scene = make_system(db_session, db_settings, make_game(db_session), shift_px=(0.0, 0.0, 80.0))
    system = _stored(db_session, scene.system_id)
    figures = (system.views_total, system.views_admitted, system.worst_error_px, system.label_doubts)
    system.derived_version, system.views_total, system.worst_error_px, system.label_doubts = 0, 0, None, 0
    system.doubts.clear()
    db_session.commit()
    assert refresh_stale_systems(db_session, db_settings) == 1
    system = _stored(db_session, scene.system_id)
    assert system.derived_version == DERIVED_VERSION
    assert (system.views_total, system.views_admitted, system.worst_error_px, system.label_doubts) == figures
    assert refresh_stale_systems(db_session, db_settings) == 0
