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


def _after_one_kept_edit(database):  # noqa: ANN001, ANN202  (the fixture's tuple)
    """``(factory, settings, kept_factory, kept, frame_id, box)`` once a process that keeps systems edited the first
    view of the fixture's first system (its ball moved 2 px from ``box``, the original)."""
    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    with kept_factory() as s:
        update_ball_label(s, fid, box=_moved(box, 2.0), settings=settings)
    return factory, settings, kept_factory, kept, fid, box


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
    stored rows' digest differs from the kept one, the edit loads, and both labels are in the stored result.
    SQLite reads the digest before it uses kept objects (a read in the process). PostgreSQL uses trusted kept objects
    without reading first and finds them stale under its lock: it computes again from the stored rows, and the
    objects it keeps next are checked before use (the decision's write is then caught before they are used)."""
    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    postgresql = factory.kw["bind"].dialect.name == "postgresql"  # type: ignore[attr-defined]
    first, second = scene.frame_ids[0], scene.frame_ids[1]
    box1, box2 = _box(factory, first), _box(factory, second)
    with kept_factory() as s:
        update_ball_label(s, first, box=_moved(box1, 3.0), settings=settings)
    with factory() as s:  # another process: no kept systems
        update_ball_label(s, second, box=_moved(box2, -4.0), settings=settings)
    with kept_factory() as s:
        frame = update_ball_label(s, first, box=_moved(box1, 5.0), settings=settings)
        boxes = {f.id: f.ball_label.box for f in frame.system.frames}
        assert s.info[LAST_RECOMPUTATION] == ("recomputed" if postgresql else "precomputed")
    assert (kept.taken, kept.missed) == ((1, 0) if postgresql else (0, 1))
    assert boxes[second] == _moved(box2, -4.0) and boxes[first] == _moved(box1, 5.0)
    with factory() as s:
        decide_review(s, system_id=scene.system_id, status=ReviewStatus.ACCEPTED)
    with kept_factory() as s:
        update_ball_label(s, first, box=_moved(box1, 6.0), settings=settings)
        assert s.get(System, scene.system_id).review.status is ReviewStatus.PENDING  # the decision seen, and reset
    assert (kept.taken, kept.missed) == ((1, 1) if postgresql else (0, 2))
    for i in range(3):  # nobody else writes: loaded (the decision's edit ran under the lock and kept nothing), then
        # checked before use (the last kept objects were stale) and found current, then trusted again on PostgreSQL
        with kept_factory() as s:
            update_ball_label(s, first, box=_moved(box1, 7.0 + i), settings=settings)
            assert s.info[LAST_RECOMPUTATION] == "precomputed"
    assert (kept.taken, kept.missed) == ((3, 1) if postgresql else (2, 2))
    assert _box(factory, first) == _moved(box1, 9.0) and _box(factory, second) == _moved(box2, -4.0)
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


def test_kept_objects_found_stale_are_checked_before_use_until_found_current() -> None:
    """Trust (PostgreSQL's use of kept objects without reading first): kept objects are trusted unless the last ones
    of their system were found stale, by a :meth:`take` whose digest differed or a :meth:`doubt` after a trusted use;
    checked and found current, the next ones are trusted again. Frames route to their trusted system."""
    kept = KeptSystems()

    def system(ident: int) -> System:
        s = System(id=ident, name=f"{ident}.png")
        s.frames = [Frame(id=10 * ident + k, name=f"f{k}", width=1920, height=1080) for k in range(2)]
        for o in (s, *s.frames):
            make_transient_to_detached(o)
        return s

    kept.keep(system(1), "d1", [])
    assert kept.trusted_frame(10) == (1, 1920, 1080) and kept.trusted_frame(11) and kept.trusted_frame(20) is None
    taken = kept.take_trusted(1)
    assert taken is not None and taken[1] == "d1" and not kept.holds(1) and kept.trusted_frame(10) is None
    kept.doubt(1)  # its digest under the lock differed
    kept.keep(system(1), "d2", [])
    assert kept.holds(1) and kept.trusted_frame(10) is None and kept.take_trusted(1) is None and kept.holds(1)
    assert kept.take(1, "d3") is None  # checked: stale again
    kept.keep(system(1), "d3", [])
    assert kept.take_trusted(1) is None
    assert kept.take(1, "d3") is not None  # checked: current
    kept.keep(system(1), "d4", [])
    assert kept.trusted_frame(11) == (1, 1920, 1080) and kept.take_trusted(1) is not None


def test_frames_of_a_taken_system_are_the_sessions_own(database) -> None:
    """A taken system is attached to the edit's session: its frames are found there by id, and nothing is loaded
    twice (one object per row)."""
    factory, settings, kept_factory, kept, fid, box = _after_one_kept_edit(database)
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
    """Issue 29: an edit reads its game's rig rows with the stored rows' digest it compares, and the recomputation
    uses those. SQLite: once, in the snapshot, with the digest of a kept system (data_version spares the digest under
    the lock). PostgreSQL: the first edit in its snapshot, under its lock and after its writes (kept with its objects);
    the next ones, using trusted kept objects, read nothing before their lock: under it and after their writes."""
    from app.services.calibration import rigs
    import app.services.derivation.recompute as recompute_module
    import app.services.curation.writing as writing_module

    factory, settings, scene, _ = database
    kept_factory, kept = _kept_factory(factory)
    calls = []
    real = rigs.rig_rows_of
    monkeypatch.setattr(rigs, "rig_rows_of", lambda *a, **k: calls.append(1) or real(*a, **k))
    monkeypatch.setattr(recompute_module, "rig_rows_of", rigs.rig_rows_of)
    monkeypatch.setattr(writing_module, "rig_rows_of", rigs.rig_rows_of)
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    for i in range(3):
        calls.clear()
        with kept_factory() as s:
            reads = 1 if s.get_bind().dialect.name == "sqlite" else 3 if i == 0 else 2
            update_ball_label(s, fid, box=_moved(box, 2.0 + i), settings=settings)
            assert s.info[LAST_RECOMPUTATION] == "precomputed"
        assert len(calls) == reads
    assert (kept.taken, kept.missed) == (2, 0)
    assert _recomputes_to_itself(factory, scene.system_id, settings)


@pytest.mark.postgres
def test_trusted_kept_objects_spare_every_read_before_the_lock_on_postgresql(database) -> None:
    """PostgreSQL: an edit of a system whose objects this process kept and trusts sends nothing before its lock (its
    frame's facts are the kept frame's: no lookup, no BEGIN, no COMMIT), where an edit that loads sends its snapshot's
    reads."""
    import app.db.together as together
    from sqlalchemy import event

    factory, settings, scene, _ = database
    engine = factory.kw["bind"]  # type: ignore[attr-defined]
    if engine.dialect.name != "postgresql":
        pytest.skip("PostgreSQL's round trips (SQLite reads in the process)")
    kept_factory, kept = _kept_factory(factory)
    sent: list[str] = []
    event.listen(engine, "before_cursor_execute", lambda *a: sent.append(a[2].split()[0]))
    real = together.driver_statement
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    from app.services.curation import writing

    before_lock: list[list[str]] = []
    orig_hook = writing.computed_before_lock
    writing.computed_before_lock = lambda system_id: before_lock.append(list(sent))
    together.driver_statement = lambda stmt, dialect: sent.append("pipelined") or real(stmt, dialect)
    try:
        for i in range(3):
            sent.clear()
            with kept_factory() as s:
                update_ball_label(s, fid, box=_moved(box, 2.0 + i), settings=settings)
    finally:
        writing.computed_before_lock = orig_hook
        together.driver_statement = real
    assert len(before_lock[0]) > 1  # the first edit loads in its snapshot
    assert before_lock[1:] == [[], []]
    assert (kept.taken, kept.missed) == (2, 0)
    assert _recomputes_to_itself(factory, scene.system_id, settings)


def test_an_edit_validates_its_box_against_the_frame_it_writes(database) -> None:
    """A frame re-imported with another size after this process kept its system: an edit whose box fits the old size
    only is refused (422, field "box") whether its facts came from the kept frame (PostgreSQL) or were read; nothing
    is written, and the next edit works."""
    import sqlalchemy as sa

    from app.core.errors import InvalidInputError

    factory, settings, kept_factory, _, fid, box = _after_one_kept_edit(database)
    with factory() as s:  # another process re-imports the frame smaller
        s.execute(sa.update(Frame).where(Frame.id == fid).values(width=int(box[0]) - 50))
        s.commit()
    with kept_factory() as s, pytest.raises(InvalidInputError) as refused:
        update_ball_label(s, fid, box=_moved(box, 3.0), settings=settings)
    assert refused.value.field == "box"
    assert _box(factory, fid) == _moved(box, 2.0)
    inside = [10.0, 10.0, 30.0, 30.0]
    with kept_factory() as s:
        update_ball_label(s, fid, box=inside, settings=settings)
    assert _box(factory, fid) == inside


def test_an_edits_answer_reads_its_neighbours_and_presence_with_the_edits_writes(database) -> None:
    """The page an edit answers (``system_page`` after ``read_with_the_edit``) equals the page read afresh after the
    edit committed: its queue neighbours and who has the system open; on PostgreSQL those reads went with the edit's
    writes, so the page sends nothing after the ``COMMIT``, for an edit that loads and one that takes kept objects."""
    from sqlalchemy import event

    import app.db.together as together
    from app.db.models import User, UserRole
    from app.services.curation.presence import claim
    from app.services.curation.system_page import read_with_the_edit, system_page

    factory, settings, scene, second = database
    engine = factory.kw["bind"]  # type: ignore[attr-defined]
    kept_factory, kept = _kept_factory(factory)
    with factory() as s:
        other = User(name="other", role=UserRole.ANNOTATOR, password_hash="-")
        s.add(other)
        s.commit()
        claim(s, scene.system_id, other.id)
        s.commit()
    fid = scene.frame_ids[0]
    box = _box(factory, fid)
    sent: list[str] = []
    listener = lambda *a: sent.append(a[2].split()[0])  # noqa: E731
    real = together.driver_statement
    for i in range(2):  # the first edit loads, the second takes the kept objects
        with kept_factory() as s:
            read_with_the_edit(s)
            update_ball_label(s, fid, box=_moved(box, 2.0 + i), settings=settings)
            sent.clear()
            event.listen(engine, "before_cursor_execute", listener)
            together.driver_statement = lambda stmt, dialect: sent.append("pipelined") or real(stmt, dialect)
            try:
                page = system_page(s, scene.system_id)
            finally:
                event.remove(engine, "before_cursor_execute", listener)
                together.driver_statement = real
            answered = (page.prev_id, page.next_id, [p.name for p in page.open_by], page.system.worst_error_px)
        with factory() as s:
            fresh = system_page(s, scene.system_id)
            assert answered == (fresh.prev_id, fresh.next_id, [p.name for p in fresh.open_by],
                                fresh.system.worst_error_px)
        assert answered[1] == second.system_id and answered[2] == ["other"]
        if engine.dialect.name == "postgresql":
            assert sent == []
    assert kept.taken == 1
