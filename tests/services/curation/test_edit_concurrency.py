"""The one locking design of the edit path: an edit reads its system and the versions, gives its connection back,
computes, then under the write lock compares the versions and writes; it computes again when another write of what
it read committed meanwhile. Real SQLite files and PostgreSQL; threads, one edit held between its computation and
its write (``writing.begin_write`` wrapped) while another commits."""
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
from app.db.session import make_engine, make_session_factory
from app.services.curation import editing, writing
from app.services.curation.decisions import decide_review
from app.services.curation.editing import replace_field_lines, update_ball_label
from app.services.curation.writing import EditContext
from app.services.derivation.recompute import load_for_recompute, recompute_system
from benchmarks.edit_lock import dense_lines
from tests.api.factories import Scene, make_game, make_system
from tests.conftest import PG_ADMIN_URL, fresh_postgresql_database, migrate_new_database


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def database(request: pytest.FixtureRequest,
             tmp_path: Path) -> Iterator[tuple[Callable[[], Session], Settings, Scene, Scene]]:
    """A migrated SQLite file or fresh PostgreSQL database holding one game with two three-view systems (exact
    cameras, every view labelled); yields a session factory whose engine waits at most 1 s for a lock (as a
    served process would, ``V3D_WRITE_LOCK_TIMEOUT_S``), the settings and the two scenes."""
    with contextlib.ExitStack() as stack:
        url = (f"sqlite:///{tmp_path / 'edits.sqlite3'}" if request.param == "sqlite"
               else stack.enter_context(fresh_postgresql_database(PG_ADMIN_URL, migrated=True)))
        migrate_new_database(url)
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
        system = load_for_recompute(s, [system_id], predictions=settings.max_predictions_per_frame)[system_id]
        stored = list(system.triangulation.ball3d)
        if change is not None:
            change(system)
        with s.no_autoflush:
            fresh = list(recompute_system(s, system, settings).ball3d)
        s.rollback()
    return stored, fresh


def test_an_edit_computes_after_its_reads_and_stores_what_a_recomputation_gives(database) -> None:
    factory, settings, scene, _ = database
    fid = scene.frame_ids[0]
    with factory() as s:
        edit = EditContext()
        update_ball_label(s, fid, box=_moved(_box(factory, fid), 9.0), settings=settings, edit=edit)
        assert (edit.outcome, edit.attempts) == ("computed", 1) and edit.entry_id is not None
    stored, fresh = _stored_and_fresh_ball(factory, scene.system_id, settings)
    assert np.allclose(stored, fresh, atol=1e-9)
    with factory() as s:  # a review decision recomputes nothing: it reads and writes under the lock
        edit = EditContext()
        decide_review(s, system_id=scene.system_id, status=ReviewStatus.ACCEPTED, edit=edit)
        assert edit.outcome == "under_lock"


def test_an_edit_holds_no_pooled_connection_while_it_computes(database, monkeypatch) -> None:
    """Between its reads and its write an edit holds no connection of the pool (nothing of the session's transaction
    is left open) while its recomputation runs, and reads nothing more: a ball edit and a line edit."""
    import sqlalchemy as sa

    factory, settings, scene, _ = database
    engine = factory.kw["bind"]
    seen: list[tuple[int, int]] = []
    statements: list[str] = []
    real = editing.recompute_system, editing.recompute_frame

    def watched(real_fn: Callable[..., object]) -> Callable[..., object]:
        def run(session: Session, *args: object, **kwargs: object) -> object:
            checked_out, before = engine.pool.checkedout(), len(statements)
            out = real_fn(session, *args, **kwargs)
            seen.append((checked_out, len(statements) - before))
            return out
        return run

    sa.event.listen(engine, "before_cursor_execute", lambda *a: statements.append(a[2]))
    monkeypatch.setattr(editing, "recompute_system", watched(real[0]))
    monkeypatch.setattr(editing, "recompute_frame", watched(real[1]))
    fid = scene.frame_ids[0]
    with factory() as s:
        update_ball_label(s, fid, box=_moved(_box(factory, fid), 3.0), settings=settings)
        lines = s.get(Frame, fid).field_lines.lines
        s.commit()
        edit = EditContext()
        replace_field_lines(s, fid, {c: [[[x + 0.5, y] for x, y in p] for p in ps] for c, ps in lines.items()},
                            settings=settings, edit=edit)
        assert edit.outcome == "computed"
    assert seen == [(0, 0), (0, 0)]  # no pooled connection held, no statement sent


def _pairs_and_doubts(factory: Callable[[], Session], system_id: int, settings: Settings | None = None
                      ) -> tuple[list[tuple], list[tuple]]:
    """The system's stored pair and doubt rows (id first), or, given ``settings``, the ones a recomputation from its
    stored labels gives (ids None; nothing is written)."""
    with factory() as s:
        per_frame = None if settings is None else settings.max_predictions_per_frame
        system = load_for_recompute(s, [system_id], predictions=per_frame)[system_id]
        if settings is not None:
            with s.no_autoflush:
                recompute_system(s, system, settings)
        pairs = [(p.id, p.frame_a_id, p.frame_b_id, p.point, p.error_px, p.parallax_deg, p.baseline_m, p.kept, p.reason)
                 for p in system.triangulation.pairs]
        doubts = [(d.id, d.frame_id, d.kind, d.accuses_label, d.message, d.evidence, d.suggestion)
                  for d in system.doubts]
        s.rollback()
    return pairs, doubts


def test_an_edit_updates_its_pairs_and_doubts_in_place(database) -> None:
    """The edit's pairs and doubts are the rows a recomputation gives, written over the stored
    rows (same ids, no delete and re-insert), so that a pair the edit leaves as it was costs no statement."""
    factory, settings, scene, _ = database
    fid = scene.frame_ids[0]
    before_pairs, before_doubts = _pairs_and_doubts(factory, scene.system_id)
    assert len(before_pairs) == 3  # three views, every one labelled
    with factory() as s:
        edit = EditContext()
        update_ball_label(s, fid, box=_moved(_box(factory, fid), 7.0), settings=settings, edit=edit)
        assert edit.outcome == "computed"
    pairs, doubts = _pairs_and_doubts(factory, scene.system_id)
    fresh_pairs, fresh_doubts = _pairs_and_doubts(factory, scene.system_id, settings)
    assert [p[0] for p in pairs] == [p[0] for p in before_pairs]  # the same rows
    assert [p[1:] for p in pairs] == [p[1:] for p in fresh_pairs]  # holding what a recomputation gives
    assert pairs != before_pairs  # the moved label moved the pairs' points
    assert [d[1:] for d in doubts] == [d[1:] for d in fresh_doubts]
    kept = min(len(doubts), len(before_doubts))
    assert [d[0] for d in doubts[:kept]] == [d[0] for d in before_doubts[:kept]]


def test_a_recomputation_leaves_rows_whose_values_it_keeps_out_of_the_flush(database) -> None:
    """A recomputation sets only the values that change, so the unit of work flushes only the rows
    it really writes (every dirty object has a changed attribute): recomputing the stored inputs again dirties
    nothing but the triangulation's ``computed_at`` and the system's version; a moved label dirties its label and the
    derived rows it moves, never a view row or a pair it leaves as it was."""
    import sqlalchemy as sa

    from app.db.models import BallLabel, Triangulation

    factory, settings, scene, _ = database

    def changed(obj: object) -> set[str]:
        return {a.key for a in sa.inspect(obj).attrs if a.history.has_changes()}

    with factory() as s:
        system = load_for_recompute(s, [scene.system_id],
                                    predictions=settings.max_predictions_per_frame)[scene.system_id]
        with s.no_autoflush:
            recompute_system(s, system, settings)
            assert {type(o) for o in s.dirty} == {Triangulation, System}
            assert changed(system.triangulation) == {"computed_at"} and changed(system) == {"version"}
            frame = next(f for f in system.frames if f.id == scene.frame_ids[0])
            frame.ball_label.box = _moved(frame.ball_label.box, 6.0)
            recompute_system(s, system, settings)
            dirty = list(s.dirty)
        assert all(changed(o) for o in dirty), [(type(o).__name__, changed(o)) for o in dirty]
        assert not any(isinstance(o, (Frame, System)) and o is not system for o in dirty)
        assert any(isinstance(o, BallLabel) for o in dirty) and system.triangulation in dirty
        s.rollback()


def test_edits_of_two_views_interleaved_store_the_ball_of_both(database, monkeypatch) -> None:
    """Edit A computes outside the lock, is held there while edit B of another view of the same system commits,
    then compares its inputs under the lock, finds B's label, and recomputes: the stored 3D ball is the one of
    both edits, not the one A computed from the labels before B."""
    factory, settings, scene, _ = database
    fa, fb = scene.frame_ids[0], scene.frame_ids[1]
    box_a, box_b = _moved(_box(factory, fa), 12.0), _moved(_box(factory, fb), -10.0)
    computed, committed = threading.Event(), threading.Event()
    versions = {fid: _version(factory, fid) for fid in (fa, fb)}

    _hold_before_write(monkeypatch, "edit-a", computed, committed)
    outcome: dict[str, object] = {}
    thread = _ball_edit_in_thread(factory, settings, fa, box_a, outcome)
    try:
        assert computed.wait(60), "edit A never computed"
        with factory() as s:
            edit = EditContext()
            update_ball_label(s, fb, box=box_b, settings=settings, edit=edit)  # A computed, holds no lock: B goes on
            outcome["b"] = edit.outcome
        # B committed while A was held: had A held the lock, B would have waited the lock timeout and failed, and A
        # is held until B is done, so B's success says it, however long B took on a loaded machine
        a_held_throughout = thread.is_alive() and not committed.is_set()
    finally:
        committed.set()
        thread.join(60)
    assert outcome == {"a": "recomputed", "b": "computed"}, outcome
    assert a_held_throughout
    assert _box(factory, fa) == box_a and _box(factory, fb) == box_b
    # each frame's version bumped once: A's first attempt was rolled back whole
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
    while it is held (were the lock held, they would wait the 1 s lock timeout and fail: the hold lasts until they
    are done, so their success is the proof, whatever the machine's load); then the line edit stores what it
    computed."""
    factory, settings, scene, other = database
    assert settings.max_line_points_per_frame == 2000
    fid = scene.frame_ids[0]
    with factory() as s:
        lines = dense_lines(s.get(Frame, fid).field_lines.lines, settings.max_line_points_per_frame)
    computed, done = threading.Event(), threading.Event()
    timing: dict[str, float] = {}

    _hold_before_write(monkeypatch, "line-edit", computed, done)
    outcome: dict[str, object] = {}

    def line_edit() -> None:
        try:
            with factory() as s:
                timing["start"] = time.monotonic()
                edit = EditContext()
                replace_field_lines(s, fid, lines, settings=settings, edit=edit)
                outcome["lines"] = edit.outcome
        except BaseException as exc:  # noqa: BLE001  # the thread hands any failure to the test
            outcome["lines"] = exc

    thread = threading.Thread(target=line_edit, name="line-edit")
    thread.start()
    try:
        assert computed.wait(120), "the line edit never computed"
        with factory() as s:
            other_fid = other.frame_ids[1]
            update_ball_label(s, other_fid, box=_moved(_box(factory, other_fid), 4.0), settings=settings)
            decide_review(s, system_id=other.system_id, status=ReviewStatus.ACCEPTED)
        held_throughout = thread.is_alive() and not done.is_set()
    finally:
        done.set()
        thread.join(120)
    assert outcome == {"lines": "computed"}, outcome
    assert held_throughout, timing
    with factory() as s:
        stored = s.get(Frame, fid).field_lines.lines
        assert sum(len(p) for ps in stored.values() for p in ps) == 2000
        assert s.get(Frame, fid).calibration.source.value == "computed"


def _ball_edit_in_thread(factory: Callable[[], Session], settings: Settings, frame_id: int, box: list[float],
                         outcome: dict[str, object]) -> threading.Thread:
    """Start edit A (a ball edit of ``frame_id`` to ``box``) in a thread named "edit-a"; its outcome, or the exception
    it raised, goes to ``outcome["a"]``."""
    def edit_a() -> None:
        try:
            with factory() as s:
                edit = EditContext()
                update_ball_label(s, frame_id, box=box, settings=settings, edit=edit)
                outcome["a"] = edit.outcome
        except BaseException as exc:  # noqa: BLE001  # the test asserts the outcome, an exception included
            outcome["a"] = exc

    thread = threading.Thread(target=edit_a, name="edit-a")
    thread.start()
    return thread


def _hold_before_write(monkeypatch: pytest.MonkeyPatch, thread_name: str, computed: threading.Event,
                       release: threading.Event) -> None:
    """Hold the first write of the edit running in thread ``thread_name`` (after its computation, before its lock)
    until ``release``, setting ``computed`` when it gets there."""
    real = writing.begin_write
    held: list[bool] = []

    def begin_write(session: Session) -> None:
        if threading.current_thread().name == thread_name and not held:
            held.append(True)
            computed.set()
            assert release.wait(60)
        real(session)

    monkeypatch.setattr(writing, "begin_write", begin_write)


def test_an_edit_whose_games_rig_changed_meanwhile_computes_again(database, monkeypatch) -> None:
    """An edit reads its game's rig (the other systems' cameras) with its system: a line edit of another system of the
    game committed between its reads and its write (a recalibration, ``Game.version`` bumped) makes it compute again,
    so its stored mirror evidence and 3D ball are those of the new rig."""
    factory, settings, scene, other = database
    fa = scene.frame_ids[0]
    computed, committed = threading.Event(), threading.Event()
    _hold_before_write(monkeypatch, "edit-a", computed, committed)
    outcome: dict[str, object] = {}
    thread = _ball_edit_in_thread(factory, settings, fa, _moved(_box(factory, fa), 6.0), outcome)
    try:
        assert computed.wait(60), "edit A never computed"
        ob = other.frame_ids[0]
        with factory() as s:
            lines = s.get(Frame, ob).field_lines.lines
            s.commit()
            edit = EditContext()
            replace_field_lines(s, ob, {c: [[[x + 1.0, y] for x, y in p] for p in ps] for c, ps in lines.items()},
                                settings=settings, edit=edit)
            outcome["b"] = edit.outcome
    finally:
        committed.set()
        thread.join(60)
    assert outcome == {"a": "recomputed", "b": "computed"}, outcome
    pairs, doubts = _pairs_and_doubts(factory, scene.system_id)
    fresh_pairs, fresh_doubts = _pairs_and_doubts(factory, scene.system_id, settings)
    assert [p[1:] for p in pairs] == [p[1:] for p in fresh_pairs]
    assert [d[1:] for d in doubts] == [d[1:] for d in fresh_doubts]


def test_a_decision_sent_with_the_system_version_of_a_page_drawn_before_an_edit_is_stale(database) -> None:
    """The system's version covers its labels: a decision expecting the version read before a ball edit is refused
    (412, nothing decided); with the version after it, it is recorded."""
    from app.core.errors import StaleVersionError

    factory, settings, scene, _ = database
    with factory() as s:
        seen = s.get(System, scene.system_id).version
    fid = scene.frame_ids[1]
    with factory() as s:
        update_ball_label(s, fid, box=_moved(_box(factory, fid), 40.0), settings=settings)
    with factory() as s:
        with pytest.raises(StaleVersionError):
            decide_review(s, system_id=scene.system_id, status=ReviewStatus.ACCEPTED, expected={seen})
    with factory() as s:
        system = s.get(System, scene.system_id)
        assert system.review_status is ReviewStatus.PENDING
        now = system.version
        assert now > seen
        decide_review(s, system_id=scene.system_id, status=ReviewStatus.ACCEPTED, expected={now})
    with factory() as s:
        assert s.get(System, scene.system_id).review_status is ReviewStatus.ACCEPTED




def test_the_page_an_edit_answers_from_its_objects_is_the_page_read_afresh(database) -> None:
    """An edit's answer draws the system page from the objects the edit committed (``system_page._loaded_system``):
    it equals the page read afresh by a new session, for a ball edit and an exclusion."""
    from app.api.view_schemas import SystemView
    from app.services.curation.editing import set_view_excluded
    from app.services.curation.system_page import system_page

    factory, settings, scene, _ = database

    def page(s: Session) -> dict:
        return SystemView.of(system_page(s, scene.system_id)).model_dump(mode="json")

    fid = scene.frame_ids[1]
    for edit in (lambda s: update_ball_label(s, fid, box=_moved(_box(factory, fid), 5.0), settings=settings),
                 lambda s: set_view_excluded(s, scene.frame_ids[2], True, settings=settings)):
        with factory() as s:
            edit(s)
            answered = page(s)
        with factory() as s:
            assert page(s) == answered
