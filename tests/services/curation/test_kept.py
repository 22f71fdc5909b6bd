"""The systems an edit committed, kept for the next edit of the same system in the process (issue 29,
``app.services.curation.kept``): taken only while the stored rows are those it committed and its session is closed;
whatever happens between two edits, the stored rows stay what a recomputation of the stored labels gives. SQLite and
PostgreSQL (the ``database`` fixture of ``test_edit_before_lock``)."""
from __future__ import annotations

from collections.abc import Callable

import pytest
from sqlalchemy.orm import Session, make_transient_to_detached

from app.db.models import Frame, ReviewStatus, System
from app.db.session import make_session_factory
from app.services.curation.decisions import decide_review
from app.services.curation.editing import update_ball_label
from app.services.curation.kept import KEPT_SYSTEMS, KeptSystems
from app.services.curation.writing import LAST_RECOMPUTATION
from app.services.derivation.recompute import load_for_recompute, recompute_system

from tests.services.curation.test_edit_before_lock import _box, _moved, database  # noqa: F401  (the fixture)


def _kept_factory(factory: Callable[[], Session]) -> tuple[Callable[[], Session], KeptSystems]:
    """A session factory on the same engine whose sessions share one :class:`KeptSystems`, as a served process's do."""
    kept = KeptSystems()
    engine = factory.kw["bind"]  # type: ignore[attr-defined]
    return make_session_factory(engine, info={KEPT_SYSTEMS: kept}), kept


def _recomputes_to_itself(factory: Callable[[], Session], system_id: int, settings) -> bool:
    """True when recomputing the system's stored labels changes no stored row but the triangulation's time stamp."""
    from app.db.models import Triangulation

    with factory() as s:
        system = load_for_recompute(s, [system_id])[system_id]
        with s.no_autoflush:
            recompute_system(s, system, settings)
            dirty = {type(o) for o in s.dirty}
        s.rollback()
    return dirty == {Triangulation}


def test_consecutive_edits_of_a_system_take_the_objects_the_last_one_committed(database) -> None:
    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    for i in range(4):
        with kept_factory() as s:
            frame = update_ball_label(s, fid, box=_moved(box, 2.0 + i), settings=settings)
            assert s.info[LAST_RECOMPUTATION] == "precomputed"
            assert frame.ball_label.box == _moved(box, 2.0 + i)
    assert (kept.taken, kept.missed) == (3, 0)  # the first edit loaded (nothing kept yet), the others took
    assert _box(factory, fid) == _moved(box, 5.0)
    assert _recomputes_to_itself(factory, scene.system_id, settings)


def test_a_write_between_two_edits_makes_the_next_load_what_is_stored(database) -> None:
    """Another process's edit of a sibling view, then a decision, between two edits of this process: each time the
    stored rows' digest differs from the kept one, the edit loads, and both labels are in the stored result."""
    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    first, second = scene.frame_ids[0], scene.frame_ids[1]
    box1, box2 = _box(factory, first), _box(factory, second)
    with kept_factory() as s:
        update_ball_label(s, first, box=_moved(box1, 3.0), settings=settings)
    with factory() as s:  # another process: no kept systems
        update_ball_label(s, second, box=_moved(box2, -4.0), settings=settings)
    with kept_factory() as s:
        frame = update_ball_label(s, first, box=_moved(box1, 5.0), settings=settings)
        boxes = {f.id: f.ball_label.box for f in frame.system.frames}
    assert (kept.taken, kept.missed) == (0, 1)
    assert boxes[second] == _moved(box2, -4.0) and boxes[first] == _moved(box1, 5.0)
    with factory() as s:
        decide_review(s, system_id=scene.system_id, status=ReviewStatus.ACCEPTED)
    with kept_factory() as s:
        update_ball_label(s, first, box=_moved(box1, 6.0), settings=settings)
        assert s.get(System, scene.system_id).review.status is ReviewStatus.PENDING  # the decision seen, and reset
    assert (kept.taken, kept.missed) == (0, 2)
    assert _recomputes_to_itself(factory, scene.system_id, settings)


def test_objects_still_held_by_an_open_session_are_not_taken(database) -> None:
    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    holder = kept_factory()
    update_ball_label(holder, fid, box=_moved(box, 2.0), settings=settings)  # its session stays open
    with kept_factory() as s:
        update_ball_label(s, fid, box=_moved(box, 3.0), settings=settings)
    holder.close()
    assert (kept.taken, kept.missed) == (0, 1)
    assert _box(factory, fid) == _moved(box, 3.0)


def test_kept_systems_are_bounded_and_taken_once() -> None:
    kept = KeptSystems(max_systems=2)
    systems = [System(id=i, name=f"{i}.png") for i in (1, 2, 3)]
    for s in systems:
        make_transient_to_detached(s)  # as a closed session leaves them
        kept.keep(s, f"digest-{s.id}", [s])
    assert len(kept) == 2 and kept.take(1, "digest-1") is None  # the oldest dropped
    assert kept.take(2, "other") is None and kept.take(2, "digest-2") is None  # a wrong digest removes it too
    assert kept.take(3, "digest-3") is systems[2] and kept.take(3, "digest-3") is None
    systems[2].name = "changed in memory, never written"
    kept.keep(systems[2], "digest-3", [systems[2]])
    assert kept.take(3, "digest-3") is None
    with pytest.raises(ValueError, match="at least 1"):
        KeptSystems(0)


def test_frames_of_a_taken_system_are_the_sessions_own(database) -> None:
    """A taken system is attached to the edit's session: its frames are found there by id, and nothing is loaded
    twice (one object per row)."""
    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    with kept_factory() as s:
        update_ball_label(s, fid, box=_moved(box, 2.0), settings=settings)
    with kept_factory() as s:
        frame = update_ball_label(s, fid, box=_moved(box, 3.0), settings=settings)
        assert kept.taken == 1
        assert s.get(Frame, fid) is frame and frame in s and frame.system in s
        assert all(f in s for f in frame.system.frames)


def test_the_apps_edits_take_the_kept_system_and_answer_as_a_fresh_load(tmp_path) -> None:
    """Through the served app (its sessions share one KeptSystems): consecutive ball edits of a view take the system
    the last one committed, and each answer equals the page read afterwards by a fresh load (GET)."""
    from fastapi.testclient import TestClient

    from app.core.config import Settings
    from app.db.session import upgrade_database
    from app.main import create_app

    from tests.accounts import make_accounts
    from tests.api.factories import make_game, make_system

    url = f"sqlite:///{tmp_path / 'kept.sqlite3'}"
    upgrade_database(url)
    settings = Settings(_env_file=None, database_url=url, job_runner=False, calibration_workers=1)
    admin = make_accounts(url, login=False, roles=("admin",))["admin"]
    app = create_app(settings)
    with app.state.session_factory() as s:
        scene = make_system(s, settings, make_game(s), "1.png")
        s.commit()
    kept = app.state.session_factory.kw["info"][KEPT_SYSTEMS]
    fid = scene.frame_ids[0]
    with TestClient(app, headers=admin.bearer) as client:
        etag = client.get(f"/api/frames/{fid}").headers["etag"]
        box = client.get(f"/api/frames/{fid}").json()["ball"]["box"]
        for i in range(3):
            r = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 2.0 + i)}, headers={"If-Match": etag})
            assert r.status_code == 200, r.text
            etag = r.headers["etag"]
            page = client.get(f"/api/systems/{scene.system_id}").json()
            answer = r.json()
            assert answer["views"] == page["views"] and answer["triangulation"] == page["triangulation"]
            assert answer["doubts"] == page["doubts"]
    assert (kept.taken, kept.missed) == (2, 0)


def test_a_kept_system_reads_its_rig_rows_with_its_digest_once(database, monkeypatch) -> None:
    """Issue 29: the edit that takes a kept system reads its game's rig rows with the stored rows' digest it compares
    (one round trip on PostgreSQL), and the recomputation uses those: once in the snapshot, once more under the lock
    on PostgreSQL only (SQLite's data_version spares the digest there), as an edit that loads."""
    from app.services.calibration import rigs
    import app.services.derivation.recompute as recompute_module

    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    calls = []
    real = rigs.rig_rows_of
    monkeypatch.setattr(rigs, "rig_rows_of", lambda *a, **k: calls.append(1) or real(*a, **k))
    monkeypatch.setattr(recompute_module, "rig_rows_of", rigs.rig_rows_of)
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    for i in range(3):
        calls.clear()
        with kept_factory() as s:
            reads = 1 if s.get_bind().dialect.name == "sqlite" else 2
            update_ball_label(s, fid, box=_moved(box, 2.0 + i), settings=settings)
            assert s.info[LAST_RECOMPUTATION] == "precomputed"
        assert len(calls) == reads
    assert (kept.taken, kept.missed) == (2, 0)
    assert _recomputes_to_itself(factory, scene.system_id, settings)
