"""The concurrency check covers what an edit reads, and every write of it bumps the version that covers it.

``app.db.scope`` declares what an edit of a system reads: the tables ``System.version`` covers and the
tables ``Game.version`` covers (the game's rig and camera prior). Two records on a real SQLite file pin it:

* the tables of every statement an edit sends before its write (a ball edit, a line edit, an exclusion, a mirroring:
  each reads its system, its game's rig) are covered, and none is sent while it computes;
* every committed transaction that writes a covered table, through every kind of writer (the edits, the decisions,
  an undo (one that gives decisions back too) and a revert, the full recompute, an import, a merge into stored games
  and the revert of what it changed), also bumps the version that covers it.

Removing a relation from the declaration (say the optimised box) makes an edit read it while computing (refused) and
leaves its table uncovered: both records fail.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db import scope
from app.db.models import AuditEntry, Frame, ReviewStatus, System
from app.db.session import make_engine, make_session_factory
from app.services.curation import writing
from app.services.curation.decisions import decide_calibration, decide_review
from app.services.curation.editing import (
    apply_mirrored_labels,
    replace_field_lines,
    set_view_excluded,
    update_ball_label,
)
from app.services.curation.reverting import revert_entry, undo_entry
from app.services.curation.writing import EditContext
from app.services.derivation.recompute import recompute_all_systems
from tests.api.factories import Scene, make_game, make_system
from tests.conftest import migrate_new_database

_TABLES = re.compile(r'\b(?:FROM|JOIN)\s+"?(\w+)"?', re.IGNORECASE)
_WRITE = re.compile(r'^\s*(INSERT INTO|UPDATE|DELETE FROM)\s+"?(\w+)"?(.*)$', re.IGNORECASE | re.DOTALL)


class Recorder:
    """Every statement an engine sends, grouped by transaction (a commit or a rollback ends one)."""

    def __init__(self, engine: sa.Engine) -> None:
        self.current: list[str] = []
        self.committed: list[list[str]] = []
        self.marks: list[str] = []
        sa.event.listen(engine, "before_cursor_execute", lambda *a: self.current.append(a[2]))
        sa.event.listen(engine, "commit", lambda _conn: self._end(True))
        sa.event.listen(engine, "rollback", lambda _conn: self._end(False))

    def _end(self, committed: bool) -> None:
        if committed and self.current:
            self.committed.append(self.current)
        self.current = []


@pytest.fixture
def database(tmp_path: Path) -> Iterator[tuple[Callable[[], Session], Settings, Scene, Recorder]]:
    url = f"sqlite:///{tmp_path / 'scope.sqlite3'}"
    migrate_new_database(url)
    settings = Settings(_env_file=None, database_url=url, calibration_workers=1, job_runner=False)
    engine = make_engine(url)
    factory = make_session_factory(engine)
    with factory() as s:
        game = make_game(s)
        scene = make_system(s, settings, game, "1.png")
        make_system(s, settings, game, "2.png")
    yield factory, settings, scene, Recorder(engine)
    engine.dispose()


def _moved(box: list[float], dx: float) -> list[float]:
    return [box[0] + dx, box[1], box[2] + dx, box[3]]


def _edits(factory: Callable[[], Session], settings: Settings, scene: Scene) -> list[Callable[[Session], object]]:
    fid = scene.frame_ids[0]
    with factory() as s:
        box, lines = list(s.get(Frame, fid).ball_label.box), s.get(Frame, fid).field_lines.lines
    nudged = {c: [[[x + 0.5, y] for x, y in p] for p in ps] for c, ps in lines.items()}
    return [
        lambda s: update_ball_label(s, fid, box=_moved(box, 4.0), settings=settings),
        lambda s: replace_field_lines(s, fid, nudged, settings=settings),
        lambda s: set_view_excluded(s, scene.frame_ids[1], True, settings=settings),
        lambda s: apply_mirrored_labels(s, scene.frame_ids[2], settings=settings),
    ]


def test_an_edit_reads_only_what_the_versions_cover_and_nothing_while_it_computes(database, monkeypatch) -> None:
    factory, settings, scene, recorder = database
    covered = scope.system_tables() | scope.game_tables()
    phases: dict[str, list[str]] = {"read": [], "compute": []}
    phase = {"now": "read"}
    real_end, real_begin = writing.end_reads, writing.begin_write

    def end_reads(session: Session) -> None:
        real_end(session)
        phases["read"].extend(recorder.current + [s for t in recorder.committed[-1:] for s in t])
        recorder.current, phase["now"] = [], "compute"

    def begin_write(session: Session) -> None:
        phases["compute"].extend(recorder.current)
        phase["now"] = "write"
        real_begin(session)

    monkeypatch.setattr(writing, "end_reads", end_reads)
    monkeypatch.setattr(writing, "begin_write", begin_write)
    for edit in _edits(factory, settings, scene):
        with factory() as s:
            recorder.current, recorder.committed = [], []
            try:
                edit(s)
            except Exception as exc:  # the mirroring's guard may refuse; it read and computed all the same
                assert "mirror" in str(exc)
            read = {t.lower() for stmt in phases["read"] for t in _TABLES.findall(stmt)}
            assert read and read <= covered, read - covered
    assert phases["compute"] == [], phases["compute"]  # no statement while computing


def _written(statements: list[str]) -> dict[str, list[str]]:
    """Table -> the SET clauses (or "" for an insert or a delete) of the writes among ``statements``."""
    out: dict[str, list[str]] = {}
    for stmt in statements:
        m = _WRITE.match(stmt)
        if m:
            verb, table, rest = m.group(1).upper(), m.group(2).lower(), m.group(3)
            out.setdefault(table, []).append(rest.split(" WHERE ")[0] if verb == "UPDATE" else verb)
    return out


#: What a view's decision writes: its review row and its frame's version (which covers it, scope's docstring).
_VIEW_DECISION = frozenset({"frames", "review_decisions"})
#: Columns of ``systems`` no edit reads for its recomputation nor writes: an assignment changes them alone.
_ASSIGNMENT = ("assignee_id", "assigned_at", "assigned_by")


def _check_covered(transactions: list[list[str]]) -> int:
    """Assert that each committed transaction writing a covered table bumps the version covering it; returns how many
    such transactions there were."""
    checked = 0
    rig = scope.game_tables() - {"frames", "systems"}
    for statements in transactions:
        written = _written(statements)
        system_writes = {t: sets for t, sets in written.items() if t in scope.system_tables()}
        if "systems" in system_writes and all(any(c in s for c in _ASSIGNMENT) for s in system_writes["systems"]):
            del system_writes["systems"]
        if not system_writes:
            continue
        checked += 1
        bumped = any("INSERT" in s or re.search(r"\bversion\s*=", s) for s in written.get("systems", []))
        view_decision = set(system_writes) <= _VIEW_DECISION and any(
            re.search(r"\bedit_version\s*=", s) for s in written.get("frames", []))
        assert bumped or view_decision, f"a transaction wrote {sorted(system_writes)} without bumping the version"
        camera_writes = [s for t in rig for s in written.get(t, []) if re.search(r"\b(camera|status|jac_\w+)\s*=", s)
                         or "INSERT" in s]
        if camera_writes:
            game_bumped = any(re.search(r"\bversion\s*=", s) or "INSERT" in s for s in written.get("games", []))
            assert game_bumped, "a transaction changed a calibration of a rig without bumping its game's version"
    return checked


def test_every_write_of_what_an_edit_reads_bumps_its_version(database) -> None:
    factory, settings, scene, recorder = database
    recorder.committed = []
    for edit in _edits(factory, settings, scene):
        with factory() as s:
            try:
                edit(s)
            except Exception as exc:  # a refused mirroring writes nothing
                assert "mirror" in str(exc)
    fid = scene.frame_ids[0]
    with factory() as s:
        decide_review(s, frame_id=fid, status=ReviewStatus.ACCEPTED)
        decide_calibration(s, fid, status=ReviewStatus.ACCEPTED)
        decide_review(s, system_id=scene.system_id, status=ReviewStatus.ACCEPTED)
    with factory() as s:
        box = list(s.get(Frame, fid).ball_label.box)
        edit = EditContext()
        update_ball_label(s, fid, box=_moved(box, -3.0), settings=settings, actor="ana", edit=edit)
    with factory() as s:
        undo_entry(s, edit.entry_id, settings=settings, actor="ana", may_review=True)
        assert s.get(System, scene.system_id).review_status is ReviewStatus.ACCEPTED  # it gave the decisions back
    with factory() as s:
        revert_entry(s, edit.entry_id, settings=settings, actor="rita", force=True)
    with factory() as s:
        recompute_all_systems(s, settings)
    assert _check_covered(recorder.committed) >= 11


@pytest.mark.shared
def test_an_import_bumps_the_versions_of_what_it_writes(tmp_path: Path, v3_tree: Path) -> None:
    from app.services.transfer.importing import import_soccernet_v3

    url = f"sqlite:///{tmp_path / 'import.sqlite3'}"
    migrate_new_database(url)
    settings = Settings(_env_file=None, database_url=url, calibration_workers=1, job_runner=False)
    engine = make_engine(url)
    try:
        recorder = Recorder(engine)
        with make_session_factory(engine)() as s:
            import_soccernet_v3(s, v3_tree, settings)
        assert _check_covered(recorder.committed) >= 1
        with make_session_factory(engine)() as s:
            assert s.scalar(sa.select(sa.func.min(System.version))) >= 1
        # a merge of stored games (a ball edited and a system accepted since, both replaced) and the revert of the
        # entry it wrote for the system are writers too
        with make_session_factory(engine)() as s:
            frame = s.scalars(sa.select(Frame).join(Frame.ball_label).order_by(Frame.id)).first()
            system_id = frame.system_id
            update_ball_label(s, frame.id, box=_moved(list(frame.ball_label.box), 6.0), settings=settings)
        with make_session_factory(engine)() as s:
            decide_review(s, system_id=system_id, status=ReviewStatus.ACCEPTED)
        recorder.committed = []
        with make_session_factory(engine)() as s:
            assert import_soccernet_v3(s, v3_tree, settings, merge="overwrite").systems_merged == 1
        assert _check_covered(recorder.committed) >= 1
        with make_session_factory(engine)() as s:
            entry = s.scalars(sa.select(AuditEntry).where(AuditEntry.action == "system.import")).one()
            recorder.committed = []
            revert_entry(s, entry.id, settings=settings)
        assert _check_covered(recorder.committed) >= 1
    finally:
        engine.dispose()
