"""The one locking design of the edit path (issue 27, item 4): an edit computes its recomputation in a read
snapshot before it takes the write lock, and under the lock only compares every input it read and writes; it
recomputes under the lock only when an input changed meanwhile. Real SQLite files (two engines stand for two
server processes) and PostgreSQL; threads, and the hook ``writing.computed_before_lock`` holding one edit
between its geometry and its lock while the other commits."""
from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Frame, ReviewStatus, System
from app.db.session import make_engine, make_session_factory, upgrade_database
from app.services.curation import editing, writing
from app.services.curation.writing import LAST_RECOMPUTATION
from app.services.curation.decisions import decide_review
from app.services.curation.editing import replace_field_lines, update_ball_label
from app.services.derivation.recompute import load_for_recompute, recompute_system

from benchmarks.edit_lock import dense_lines
from tests.api.factories import Scene, make_game, make_system
from tests.conftest import PG_ADMIN_URL, fresh_postgresql_database


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def database(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[Callable[[], Session], Settings, Scene, Scene]]:
    """A migrated SQLite file or fresh PostgreSQL database holding one game with two three-view systems (exact
    cameras, every view labelled); yields a session factory whose engine waits at most 1 s for a lock (as a
    served process would, ``V3D_WRITE_LOCK_TIMEOUT_S``), the settings and the two scenes."""
    with contextlib.ExitStack() as stack:
        url = (f"sqlite:///{tmp_path / 'edits.sqlite3'}" if request.param == "sqlite"
               else stack.enter_context(fresh_postgresql_database(PG_ADMIN_URL)))
        upgrade_database(url)
        settings = Settings(_env_file=None, database_url=url, calibration_workers=1, job_runner=False,
                            write_lock_timeout_s=1.0)
        engine = make_engine(url, write_lock_timeout_s=settings.write_lock_timeout_s)
        stack.callback(engine.dispose)
        factory = make_session_factory(engine)
        with factory() as s:
            game = make_game(s)
            first = make_system(s, settings, game, "1.png")
            second = make_system(s, settings, game, "2.png")
        yield factory, settings, first, second


def _moved(box: list[float], dx: float) -> list[float]:
    return [box[0] + dx, box[1], box[2] + dx, box[3]]


def _box(factory: Callable[[], Session], frame_id: int) -> list[float]:
    with factory() as s:
        return list(s.get(Frame, frame_id).ball_label.box)


def _version(factory: Callable[[], Session], frame_id: int) -> int:
    with factory() as s:
        return s.get(Frame, frame_id).edit_version


def _stored_and_fresh_ball(factory: Callable[[], Session], system_id: int, settings: Settings,
                           change: Callable[[System], None] | None = None) -> tuple[list[float], list[float]]:
    """The stored 3D ball of the system and the one a recomputation from its stored labels gives (after
    ``change`` of them in memory; nothing is written)."""
    with factory() as s:
        system = load_for_recompute(s, [system_id])[system_id]
        stored = list(system.triangulation.ball3d)
        if change is not None:
            change(system)
        with s.no_autoflush:
            fresh = list(recompute_system(s, system, settings).ball3d)
        s.rollback()
    return stored, fresh


def test_an_edit_computes_before_the_lock_and_stores_what_a_recomputation_gives(database) -> None:
    factory, settings, scene, _ = database
    fid = scene.frame_ids[0]
    with factory() as s:
        update_ball_label(s, fid, box=_moved(_box(factory, fid), 9.0), settings=settings)
        assert s.info[LAST_RECOMPUTATION] == "precomputed"  # stored as computed outside the lock
    stored, fresh = _stored_and_fresh_ball(factory, scene.system_id, settings)
    assert np.allclose(stored, fresh, atol=1e-9)
    with factory() as s:  # a review decision recomputes nothing: nothing computed before its lock
        decide_review(s, system_id=scene.system_id, status=ReviewStatus.ACCEPTED)
        assert s.info[LAST_RECOMPUTATION] == "under_lock"


def _pairs_and_doubts(factory: Callable[[], Session], system_id: int, settings: Settings | None = None
                      ) -> tuple[list[tuple], list[tuple]]:
    """The system's stored pair and doubt rows (id first), or, given ``settings``, the ones a recomputation from its
    stored labels gives (ids None; nothing is written)."""
    with factory() as s:
        system = load_for_recompute(s, [system_id])[system_id]
        if settings is not None:
            with s.no_autoflush:
                recompute_system(s, system, settings)
        pairs = [(p.id, p.frame_a_id, p.frame_b_id, p.point, p.error_px, p.parallax_deg, p.baseline_m, p.kept, p.reason)
                 for p in system.triangulation.pairs]
        doubts = [(d.id, d.frame_id, d.kind, d.accuses_label, d.message, d.evidence, d.suggestion) for d in system.doubts]
        s.rollback()
    return pairs, doubts


def test_an_edit_updates_its_pairs_and_doubts_in_place(database) -> None:
    """Issue 29, item 2: the edit's pairs and doubts are the rows a recomputation gives, written over the stored
    rows (same ids, no delete and re-insert), so that a pair the edit leaves as it was costs no statement."""
    factory, settings, scene, _ = database
    fid = scene.frame_ids[0]
    before_pairs, before_doubts = _pairs_and_doubts(factory, scene.system_id)
    assert len(before_pairs) == 3  # three views, every one labelled
    with factory() as s:
        update_ball_label(s, fid, box=_moved(_box(factory, fid), 7.0), settings=settings)
        assert s.info[LAST_RECOMPUTATION] == "precomputed"
    pairs, doubts = _pairs_and_doubts(factory, scene.system_id)
    fresh_pairs, fresh_doubts = _pairs_and_doubts(factory, scene.system_id, settings)
    assert [p[0] for p in pairs] == [p[0] for p in before_pairs]  # the same rows
    assert [p[1:] for p in pairs] == [p[1:] for p in fresh_pairs]  # holding what a recomputation gives
    assert pairs != before_pairs  # the moved label moved the pairs' points
    assert [d[1:] for d in doubts] == [d[1:] for d in fresh_doubts]
    kept = min(len(doubts), len(before_doubts))
    assert [d[0] for d in doubts[:kept]] == [d[0] for d in before_doubts[:kept]]


def test_a_recomputation_leaves_rows_whose_values_it_keeps_out_of_the_flush(database) -> None:
    """Issue 29, item 2: a recomputation sets only the values that change, so the unit of work flushes only the rows
    it really writes (every dirty object has a changed attribute): recomputing the stored inputs again dirties
    nothing but the triangulation's ``computed_at``; a moved label dirties its label and the derived rows it moves,
    never a view row or a pair it leaves as it was."""
    import sqlalchemy as sa

    from app.db.models import BallLabel, Triangulation

    factory, settings, scene, _ = database

    def changed(obj: object) -> set[str]:
        return {a.key for a in sa.inspect(obj).attrs if a.history.has_changes()}

    with factory() as s:
        system = load_for_recompute(s, [scene.system_id])[scene.system_id]
        with s.no_autoflush:
            recompute_system(s, system, settings)
            assert {type(o) for o in s.dirty} == {Triangulation}
            assert changed(system.triangulation) == {"computed_at"}
            frame = next(f for f in system.frames if f.id == scene.frame_ids[0])
            frame.ball_label.box = _moved(frame.ball_label.box, 6.0)
            recompute_system(s, system, settings)
            dirty = list(s.dirty)
        assert all(changed(o) for o in dirty), [(type(o).__name__, changed(o)) for o in dirty]
        assert not any(isinstance(o, (Frame, System)) and o is not system for o in dirty)
        assert any(isinstance(o, BallLabel) for o in dirty) and system.triangulation in dirty
        s.rollback()


def test_an_edit_writes_its_derived_rows_directly_as_the_unit_of_work_would(database, monkeypatch) -> None:
    """Issue 29: an edit computed before its lock sends the derived rows it changed as one UPDATE per table and
    columns (``rows.writing_directly``), not through the unit of work, which flushes only the edited label and the
    audit entry. The stored rows are then exactly what a recomputation of the stored labels gives (recomputing them
    changes nothing but the triangulation's time stamp), the objects the edit answers from equal the stored rows,
    and a calibration's ``updated_at`` moved as its ``onupdate`` says."""
    import sqlalchemy as sa

    from app.db.models import Calibration, Triangulation
    from app.services.derivation import rows

    factory, settings, scene, _ = database
    fid = scene.frame_ids[0]
    sent: list[int] = []
    write = rows.DirectWrites.write
    monkeypatch.setattr(rows.DirectWrites, "write",
                        lambda self, session, after=(): sent.append(len(self)) or write(self, session, after))

    with factory() as s:
        updated = {c.frame_id: c.updated_at for c in s.scalars(sa.select(Calibration).where(
            Calibration.frame_id.in_(scene.frame_ids)))}
    with factory() as s:
        frame = update_ball_label(s, fid, box=_moved(_box(factory, fid), 5.0), settings=settings)
        assert s.info[LAST_RECOMPUTATION] == "precomputed"
        assert sent and sent[0] >= 6  # the pairs, reprojections, boxes, calibrations (mirror evidence), triangulation
        system = frame.system
        in_memory = {f.id: (f.calibration.mirror_evidence, f.calibration.updated_at, f.reprojection.point,
                            f.optimised_box.box) for f in system.frames}
        ball3d = list(system.triangulation.ball3d)
        pairs = [(p.id, p.point, p.error_px) for p in system.triangulation.pairs]
    with factory() as s:
        loaded = load_for_recompute(s, [scene.system_id])[scene.system_id]
        assert {f.id: (f.calibration.mirror_evidence, f.calibration.updated_at, f.reprojection.point,
                       f.optimised_box.box) for f in loaded.frames} == in_memory
        assert list(loaded.triangulation.ball3d) == ball3d
        assert [(p.id, p.point, p.error_px) for p in loaded.triangulation.pairs] == pairs
        assert len(updated) == len(scene.frame_ids)
        assert all(f.calibration.updated_at > updated[f.id] for f in loaded.frames)
        with s.no_autoflush:
            recompute_system(s, loaded, settings)
            assert {type(o) for o in s.dirty} == {Triangulation}  # the stored rows are what it gives
        s.rollback()


def test_direct_writes_refuse_a_row_gone_and_leave_new_rows_to_the_unit_of_work(database) -> None:
    """A stored row collected by ``rows.writing_directly`` that vanished before the write fails the write
    (StaleDataError, nothing silently lost); a row not stored yet is set on the object, for the unit of work."""
    import sqlalchemy as sa
    from sqlalchemy.orm.exc import StaleDataError

    from app.db.models import BallReprojection, OptimisedBox
    from app.services.derivation.rows import put_values, writing_directly

    factory, settings, scene, _ = database
    with factory() as s:
        frame = s.get(Frame, scene.frame_ids[0])
        with writing_directly(s) as direct:
            put_values(frame.reprojection, {"error_px": 123.0})
            fresh = put_values(OptimisedBox(box=[0.0, 0.0, 1.0, 1.0], d_opt_px=1.0, error_m=0.0), {"d_opt_px": 2.0})
        assert len(direct) == 1 and not s.dirty and fresh.d_opt_px == 2.0
        assert frame.reprojection.error_px == 123.0
        # gone behind the session's back (as another connection's delete): the session still holds the row
        s.execute(sa.delete(BallReprojection).where(BallReprojection.frame_id == frame.id),
                  execution_options={"synchronize_session": False})
        with pytest.raises(StaleDataError, match="ball_reprojections: 1 rows to update, 0 found"):
            direct.write(s)
        s.rollback()
    with factory() as s:  # deleted by the session's own unit of work (flushed before the direct writes): left out
        frame = s.get(Frame, scene.frame_ids[0])
        box = frame.optimised_box
        with writing_directly(s) as direct:
            put_values(frame.reprojection, {"error_px": 124.0})
            put_values(box, {"d_opt_px": 3.0})
        s.delete(box)
        s.flush()
        assert direct.write(s) == []
        assert s.get(BallReprojection, frame.id).error_px == 124.0 and s.get(OptimisedBox, frame.id) is None
        s.rollback()


def test_direct_writes_of_several_rows_store_each_value_as_a_single_write_would(database) -> None:
    """The rows of one table and columns written together (one executemany UPDATE) store each row's own values: JSON
    documents, numbers, time stamps, None; on PostgreSQL None as SQL NULL (``IS NULL`` finds it: the statements go
    through the driver, ``app.db.together``; SQLite's, executed by SQLAlchemy, store JSON ``null``, which reads back
    as None too)."""
    from datetime import datetime, timezone

    import sqlalchemy as sa

    from app.db.models import Calibration
    from app.services.derivation.rows import put_values, writing_directly

    factory, settings, scene, _ = database
    when = datetime(2026, 1, 2, 3, 4, 5, 678000, tzinfo=timezone.utc)
    with factory() as s:
        frames = [s.get(Frame, fid) for fid in scene.frame_ids]
        with writing_directly(s) as direct:
            for i, frame in enumerate(frames):
                put_values(frame.calibration, {"mirror_evidence": None if i == 1 else {"i": i, "x": [0.5, i]},
                                               "updated_at": when})
                put_values(frame.reprojection, {"error_px": 0.25 + i, "point": [1.5 * i, 2.0]})
        assert len(direct) == 2 * len(frames)
        direct.write(s)
        s.commit()
    with factory() as s:
        nulls = s.scalars(sa.select(Calibration.frame_id).where(Calibration.frame_id.in_(scene.frame_ids),
                                                               Calibration.mirror_evidence.is_(None))).all()
        if s.get_bind().dialect.name == "postgresql":  # as a single write through the driver stores None
            assert nulls == [scene.frame_ids[1]]
        for i, fid in enumerate(scene.frame_ids):
            frame = s.get(Frame, fid)
            assert frame.calibration.mirror_evidence == (None if i == 1 else {"i": i, "x": [0.5, i]})
            assert frame.calibration.updated_at == when
            assert (frame.reprojection.error_px, frame.reprojection.point) == (0.25 + i, [1.5 * i, 2.0])


def test_an_edit_reads_its_games_rig_rows_once_per_digest(database, monkeypatch) -> None:
    """Issue 29: the rig rows the stored rows' digest reads are the ones the recomputation uses (the mirror evidence's
    rig, a line edit's rig retry): an edit reads them once before the lock and, on PostgreSQL, once more under it
    for the comparison (SQLite's data_version says that nobody committed meanwhile, so the digest is not read
    again), for a ball edit as for a line edit, and stores what a recomputation gives."""
    from app.services.calibration import rigs

    factory, settings, scene, _ = database
    calls = []
    real = rigs.rig_rows_of  # every read of rig rows: alone (rigs.rig_rows) or with the digest (read_stored_state)
    monkeypatch.setattr(rigs, "rig_rows_of", lambda *a, **k: calls.append(1) or real(*a, **k))
    import app.services.derivation.recompute as recompute_module
    monkeypatch.setattr(recompute_module, "rig_rows_of", rigs.rig_rows_of)
    fid = scene.frame_ids[0]
    with factory() as s:
        reads = 1 if s.get_bind().dialect.name == "sqlite" else 2
        update_ball_label(s, fid, box=_moved(_box(factory, fid), 5.0), settings=settings)
        assert s.info[LAST_RECOMPUTATION] == "precomputed"
    assert len(calls) == reads
    calls.clear()
    with factory() as s:
        lines = s.get(Frame, fid).field_lines.lines
        lines = {cls: [[[x + 0.5, y] for x, y in poly] for poly in polys] for cls, polys in lines.items()}
        editing.replace_field_lines(s, fid, lines, settings=settings)
        assert s.info[LAST_RECOMPUTATION] == "precomputed"
    assert len(calls) == reads
    pairs, doubts = _pairs_and_doubts(factory, scene.system_id)
    fresh_pairs, fresh_doubts = _pairs_and_doubts(factory, scene.system_id, settings)
    assert [p[1:] for p in pairs] == [p[1:] for p in fresh_pairs]
    assert [d[1:] for d in doubts] == [d[1:] for d in fresh_doubts]


def test_edits_of_two_views_interleaved_store_the_ball_of_both(database, monkeypatch) -> None:
    """Edit A computes outside the lock, is held there while edit B of another view of the same system commits,
    then compares its inputs under the lock, finds B's label, and recomputes: the stored 3D ball is the one of
    both edits, not the one A computed from the labels before B."""
    factory, settings, scene, _ = database
    fa, fb = scene.frame_ids[0], scene.frame_ids[1]
    box_a, box_b = _moved(_box(factory, fa), 12.0), _moved(_box(factory, fb), -10.0)
    computed, committed = threading.Event(), threading.Event()
    versions = {fid: _version(factory, fid) for fid in (fa, fb)}

    def hold_a(system_id: int) -> None:
        if threading.current_thread().name == "edit-a":
            computed.set()
            assert committed.wait(30)

    monkeypatch.setattr(writing, "computed_before_lock", hold_a)
    outcome: dict[str, object] = {}

    def edit_a() -> None:
        try:
            with factory() as s:
                update_ball_label(s, fa, box=box_a, settings=settings)
                outcome["a"] = s.info[LAST_RECOMPUTATION]
        except BaseException as exc:  # noqa: BLE001  # reported below
            outcome["a"] = exc

    thread = threading.Thread(target=edit_a, name="edit-a")
    thread.start()
    try:
        assert computed.wait(60), "edit A never computed"
        t0 = time.monotonic()
        with factory() as s:
            update_ball_label(s, fb, box=box_b, settings=settings)  # A computed but holds no lock: B goes on
            outcome["b"] = s.info[LAST_RECOMPUTATION]
        b_seconds = time.monotonic() - t0
    finally:
        committed.set()
        thread.join(60)
    assert outcome == {"a": "recomputed", "b": "precomputed"}, outcome
    assert b_seconds < settings.write_lock_timeout_s
    assert _box(factory, fa) == box_a and _box(factory, fb) == box_b
    # each frame claimed once: A's first claim (on PostgreSQL sent with the lock and the digest, which differed) was
    # rolled back with the rest of its first attempt
    assert {fid: _version(factory, fid) - v for fid, v in versions.items()} == {fa: 1, fb: 1}

    stored, both = _stored_and_fresh_ball(factory, scene.system_id, settings)
    assert np.allclose(stored, both, atol=1e-9)  # the ball of both edits

    def without_b(system: System) -> None:
        frame = next(f for f in system.frames if f.id == fb)
        frame.ball_label.box = _moved(box_b, 10.0)  # B's label as A read it

    _, a_alone = _stored_and_fresh_ball(factory, scene.system_id, settings, without_b)
    assert np.linalg.norm(np.subtract(a_alone, both)) > 1e-3  # what A computed alone was another ball


def test_an_unrelated_write_is_not_blocked_by_a_capped_size_line_edits_geometry(database, monkeypatch) -> None:
    """A field-line edit of 2,000 points (the cap) computes its calibration and recomputation outside the lock:
    held after its geometry, it holds no lock, and an edit of another system (and a review decision) commit
    at once, well within a 1 s lock timeout; then the line edit stores what it computed."""
    factory, settings, scene, other = database
    assert settings.max_line_points_per_frame == 2000
    fid = scene.frame_ids[0]
    with factory() as s:
        lines = dense_lines(s.get(Frame, fid).field_lines.lines, settings.max_line_points_per_frame)
    computed, done = threading.Event(), threading.Event()
    timing: dict[str, float] = {}

    def hold(system_id: int) -> None:
        if threading.current_thread().name == "line-edit":
            timing["geometry"] = time.monotonic() - timing["start"]
            computed.set()
            assert done.wait(30)

    monkeypatch.setattr(writing, "computed_before_lock", hold)
    outcome: dict[str, object] = {}

    def line_edit() -> None:
        try:
            with factory() as s:
                timing["start"] = time.monotonic()
                replace_field_lines(s, fid, lines, settings=settings)
                outcome["lines"] = s.info[LAST_RECOMPUTATION]
        except BaseException as exc:  # noqa: BLE001
            outcome["lines"] = exc

    thread = threading.Thread(target=line_edit, name="line-edit")
    thread.start()
    try:
        assert computed.wait(120), "the line edit never computed"
        t0 = time.monotonic()
        with factory() as s:
            other_fid = other.frame_ids[1]
            update_ball_label(s, other_fid, box=_moved(_box(factory, other_fid), 4.0), settings=settings)
            decide_review(s, system_id=other.system_id, status=ReviewStatus.ACCEPTED)
        unrelated = time.monotonic() - t0
    finally:
        done.set()
        thread.join(120)
    assert outcome == {"lines": "precomputed"}, outcome
    assert unrelated < settings.write_lock_timeout_s, (unrelated, timing)
    with factory() as s:
        stored = s.get(Frame, fid).field_lines.lines
        assert sum(len(p) for ps in stored.values() for p in ps) == 2000
        assert s.get(Frame, fid).calibration.source.value == "computed"


def test_the_stored_rows_digest_sees_every_row_an_edit_writes_and_not_the_objects_in_memory(database) -> None:
    """Issue 29: an edit carries its objects from its snapshot into its write when the digest of the stored rows read
    under the lock equals the snapshot's (``stored_state_digest``). Every row the edit may write changes it (a view's
    label, a pair, a doubt, the system's figures, a view's review, the game's camera prior); the game's release (read
    by the exports only) and the objects changed in memory but not written do not."""
    from app.db.models import Doubt, Game, ReviewDecision, TriangulationPair
    from app.services.derivation.recompute import stored_state_digest

    factory, _settings, scene, _ = database
    with factory() as s:
        first = stored_state_digest(s, scene.system_id)
        frame = s.get(Frame, scene.frame_ids[0])
        frame.ball_label.box = _moved(list(frame.ball_label.box), 3.0)  # in memory only
        with s.no_autoflush:
            assert stored_state_digest(s, scene.system_id) == first
        s.rollback()

    def changed(edit: Callable[[Session], None]) -> bool:
        with factory() as s:
            edit(s)
            s.commit()
            return stored_state_digest(s, scene.system_id) != first

    def game(s: Session) -> Game:
        return s.get(Game, s.get(System, scene.system_id).game_id)

    assert not changed(lambda s: setattr(game(s), "release", {"GameMetadata": {"UrlYoutube": "x"}}))
    for edit in (
        lambda s: setattr(s.get(Frame, scene.frame_ids[1]).ball_label, "box",
                          _moved(list(s.get(Frame, scene.frame_ids[1]).ball_label.box), 1.0)),
        lambda s: setattr(s.query(TriangulationPair).filter_by(system_id=scene.system_id).first(), "error_px", 123.0),
        lambda s: s.add(Doubt(system_id=scene.system_id, frame_id=scene.frame_ids[0], kind="test", accuses_label=False,
                              message="m", evidence={})),
        lambda s: setattr(s.get(System, scene.system_id), "views_flagged", 3),
        lambda s: setattr(s.get(Frame, scene.frame_ids[2]), "review",
                          ReviewDecision(status=ReviewStatus.ACCEPTED, comment="")),
        lambda s: setattr(game(s), "camera_prior", {"anchors_m": []}),
        lambda s: setattr(s.get(Frame, scene.frame_ids[0]).calibration, "jac_0005", 0.123),
        lambda s: setattr(s.get(Frame, scene.frame_ids[1]).field_lines, "lines", {}),
        lambda s: setattr(s.get(Frame, scene.frame_ids[2]).reprojection, "error_px", 77.0),
        lambda s: setattr(s.get(Frame, scene.frame_ids[0]), "width", 1921),
        lambda s: setattr(s.get(System, scene.system_id).triangulation, "tau_px", 21.0),
    ):
        assert changed(edit)
        with factory() as s:
            first = stored_state_digest(s, scene.system_id)


def test_the_sqlite_digest_read_by_the_driver_is_that_of_the_rows_read_through_sqlalchemy(database) -> None:
    """On SQLite ``stored_rows_digest`` reads its four statements through the driver's own cursor (compiled once):
    the same rows, hence the same digest, as the statements executed through SQLAlchemy."""
    import hashlib

    import orjson

    from app.services.derivation import recompute

    factory, settings, scene, _ = database
    with factory() as s:
        if s.get_bind().dialect.name != "sqlite":
            pytest.skip("SQLite's digest path (PostgreSQL hashes in the database)")
        for sid in (scene.system_id, _.system_id):
            doc = [[tuple(r) for r in s.execute(stmt, {"sid": sid})] for stmt in recompute._state_statements()]
            assert sum(len(rows) for rows in doc) > len(scene.frame_ids)
            expected = hashlib.sha256(orjson.dumps(doc, option=orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS,
                                                   default=str)).hexdigest()
            assert recompute.stored_rows_digest(s, sid) == expected
