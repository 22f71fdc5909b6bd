"""The turns of the recomputing edits of one process (``writing.EditSlots``): with one slot, a second edit computes
only once the first has committed, so it computes from the first's rows and never collides with it; an edit waits at
most ``wait_s`` and then computes anyway; decisions take no turn; the app hands the settings' slots to each edit's
context. A real SQLite file; threads, one edit held after its geometry (inside its turn) by a wrapped
``writing.begin_write``."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Frame, ReviewStatus
from app.db.session import make_engine, make_session_factory
from app.services.curation import writing
from app.services.curation.decisions import decide_review
from app.services.curation.editing import update_ball_label
from app.services.curation.writing import EditContext, EditSlots
from tests.api.factories import Scene, make_game, make_system
from tests.conftest import migrate_new_database


@pytest.fixture
def database(tmp_path: Path) -> Iterator[tuple[Engine, Settings, Scene, Scene]]:
    """A migrated SQLite file with one game of two three-view systems (exact cameras, every view labelled)."""
    url = f"sqlite:///{tmp_path / 'slots.sqlite3'}"
    migrate_new_database(url)
    settings = Settings(_env_file=None, database_url=url, calibration_workers=1, job_runner=False,
                        write_lock_timeout_s=5.0)
    engine = make_engine(url, write_lock_timeout_s=settings.write_lock_timeout_s)
    with make_session_factory(engine)() as s:
        game = make_game(s)
        first, second = make_system(s, settings, game, "1.png"), make_system(s, settings, game, "2.png")
    yield engine, settings, first, second
    engine.dispose()


def _moved_box(factory: Callable[[], Session], frame_id: int, dx: float) -> list[float]:
    with factory() as s:
        box = list(s.get(Frame, frame_id).ball_label.box)
    return [box[0] + dx, box[1], box[2] + dx, box[3]]


def _hold_edit_a(monkeypatch: pytest.MonkeyPatch) -> tuple[threading.Event, threading.Event, dict[str, float]]:
    """Hold the thread named "edit-a" after its geometry until ``release`` is set; note when each thread computed."""
    computed, release = threading.Event(), threading.Event()
    at: dict[str, float] = {}
    real = writing.begin_write

    def hold(session: Session) -> None:
        name = threading.current_thread().name
        if name not in at:
            at[name] = time.monotonic()
            if name == "edit-a":
                computed.set()
                assert release.wait(30)
        real(session)

    monkeypatch.setattr(writing, "begin_write", hold)
    return computed, release, at


def _in_thread(name: str, work: Callable[[], object], outcome: dict[str, object]) -> threading.Thread:
    def run() -> None:
        try:
            outcome[name] = work()
        except BaseException as exc:  # noqa: BLE001  # asserted by the test
            outcome[name] = exc
    thread = threading.Thread(target=run, name=name)
    thread.start()
    return thread


def _edit(factory: Callable[[], Session], frame_id: int, box: list[float], settings: Settings,
          slots: EditSlots) -> Callable[[], str]:
    def work() -> str:
        with factory() as s:
            edit = EditContext(slots=slots)
            update_ball_label(s, frame_id, box=box, settings=settings, edit=edit)
            return str(edit.outcome)
    return work


def test_with_one_slot_a_second_edit_computes_after_the_first_committed(database, monkeypatch) -> None:
    engine, settings, scene, _ = database
    factory, slots = make_session_factory(engine), EditSlots(1, 30.0)
    fa, fb = scene.frame_ids[0], scene.frame_ids[1]
    box_a, box_b = _moved_box(factory, fa, 6.0), _moved_box(factory, fb, -5.0)
    computed, release, at = _hold_edit_a(monkeypatch)
    outcome: dict[str, object] = {}
    a = _in_thread("edit-a", _edit(factory, fa, box_a, settings, slots), outcome)
    try:
        assert computed.wait(60), "edit A never computed"
        b = _in_thread("edit-b", _edit(factory, fb, box_b, settings, slots), outcome)
        b.join(0.5)
        assert "edit-b" not in at and "edit-b" not in outcome  # B waits for A's turn: it has not computed
        released = time.monotonic()
    finally:
        release.set()
        a.join(60)
    b.join(60)
    # B computed after A committed, from A's label: no collision, both stored as computed once
    assert outcome == {"edit-a": "computed", "edit-b": "computed"}, outcome
    assert at["edit-b"] >= released
    with factory() as s:
        assert list(s.get(Frame, fa).ball_label.box) == box_a and list(s.get(Frame, fb).ball_label.box) == box_b


def test_an_edit_computes_anyway_once_its_wait_for_a_turn_ran_out(database, monkeypatch) -> None:
    engine, settings, scene, other = database
    factory, slots = make_session_factory(engine), EditSlots(1, 0.2)
    fa, fo = scene.frame_ids[0], other.frame_ids[0]
    box_a, box_o = _moved_box(factory, fa, 6.0), _moved_box(factory, fo, 4.0)
    computed, release, at = _hold_edit_a(monkeypatch)
    outcome: dict[str, object] = {}
    a = _in_thread("edit-a", _edit(factory, fa, box_a, settings, slots), outcome)
    try:
        assert computed.wait(60), "edit A never computed"
        t0 = time.monotonic()
        b = _in_thread("edit-b", _edit(factory, fo, box_o, settings, slots), outcome)
        b.join(30)
        waited = time.monotonic() - t0
        assert outcome.get("edit-b") == "computed", outcome  # done while A still holds its turn
        assert waited >= 0.2
    finally:
        release.set()
        a.join(60)
    assert outcome["edit-a"] == "computed", outcome
    with factory() as s:
        assert list(s.get(Frame, fo).ball_label.box) == box_o and list(s.get(Frame, fa).ball_label.box) == box_a


def test_a_review_decision_takes_no_turn(database, monkeypatch) -> None:
    engine, settings, scene, other = database
    factory, slots = make_session_factory(engine), EditSlots(1, 30.0)
    fa = scene.frame_ids[0]
    computed, release, _ = _hold_edit_a(monkeypatch)
    outcome: dict[str, object] = {}
    a = _in_thread("edit-a", _edit(factory, fa, _moved_box(factory, fa, 6.0), settings, slots), outcome)
    try:
        assert computed.wait(60), "edit A never computed"
        t0 = time.monotonic()
        with factory() as s:
            decide_review(s, system_id=other.system_id, status=ReviewStatus.ACCEPTED,
                          edit=EditContext(slots=slots))
        assert time.monotonic() - t0 < settings.write_lock_timeout_s
    finally:
        release.set()
        a.join(60)
    assert outcome["edit-a"] == "computed", outcome


def test_edit_slots_count_turns_and_refuse_negative_figures() -> None:
    slots = EditSlots(2, 0.0)
    with slots.turn() as first, slots.turn() as second, slots.turn() as third:
        assert (first, second, third) == (False, False, True)  # the third waited (and ran out of its zero wait)
    with slots.turn() as again:
        assert not again  # the turns were given back: no wait
    with EditSlots(0, 10.0).turn() as unlimited:
        assert not unlimited
    for slots_, wait in ((-1, 0.5), (1, -0.1)):
        with pytest.raises(ValueError, match="slots >= 0 and wait_s >= 0"):
            EditSlots(slots_, wait)


def test_the_apps_edits_carry_the_settings_slots(tmp_path: Path) -> None:
    import asyncio
    from concurrent.futures import ThreadPoolExecutor
    from types import SimpleNamespace

    from app.api.deps import edit_context
    from app.main import create_app

    settings = Settings(_env_file=None, database_url=f"sqlite:///{tmp_path / 'app.sqlite3'}", job_runner=False,
                        edit_slots=3, edit_slot_wait_s=0.25)
    app = create_app(settings)
    request = SimpleNamespace(app=app)
    # Each in a thread of its own: a browser test run before on this worker leaves Playwright's event loop running in
    # the worker's thread, where asyncio.run refuses to start another.
    with ThreadPoolExecutor(1) as pool:
        first, second = (pool.submit(asyncio.run, edit_context(request)).result()  # type: ignore[arg-type]  # what FastAPI passes
                         for _ in range(2))
    assert first.slots is not None and (first.slots.slots, first.slots.wait_s) == (3, 0.25)
    assert second.slots is first.slots and second is not first  # one set of turns per app (process), a context per edit
    assert Settings(_env_file=None).edit_slots == 1
