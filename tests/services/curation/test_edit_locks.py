"""The row locks of concurrent edits on PostgreSQL (issue 7): ``writing.lock_system`` makes two edits of
one system (of one ISSIA sequence) wait for each other, while edits of other systems go on at once.
Two sessions on one database stand for two server processes."""
from __future__ import annotations

import threading
from collections.abc import Callable, Iterator

import pytest
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.db.models import Game, System, SystemKind
from app.db.session import begin_write, make_engine, make_session_factory
from app.services.curation.writing import lock_system

pytestmark = [pytest.mark.postgres, pytest.mark.engine]


@pytest.fixture
def systems(pg_migrated_url: str) -> Iterator[tuple[Callable[[], Session], dict[str, int]]]:
    """A session factory on a migrated PostgreSQL database holding a SoccerNet game with two systems
    and an ISSIA game with two; yields it and the system ids by name."""
    engine = make_engine(pg_migrated_url)
    factory = make_session_factory(engine)
    with factory() as s:
        v3 = Game(league="l", season="s", match="broadcast", source_path="/v3")
        v3.systems += [System(name=f"{i}.png", kind=SystemKind.SOCCERNET_V3) for i in (1, 2)]
        issia = Game(league="issia", season="sequences", match="filmA", source_path="/issia")
        issia.systems += [System(name=str(i), kind=SystemKind.ISSIA, frame_index=i) for i in (0, 1)]
        s.add_all([v3, issia])
        s.commit()
        ids = {f"{g.match}/{x.name}": x.id for g in (v3, issia) for x in g.systems}
    yield factory, ids
    engine.dispose()


def _waits_for(factory: Callable[[], Session], holder_system: int, other_system: int) -> bool:
    """Whether an edit locking ``other_system`` waits while another holds ``holder_system``'s lock
    (it must then go on once the holder commits)."""
    locked = threading.Event()

    def second() -> None:
        with factory() as s:
            begin_write(s)
            lock_system(s, other_system)
            locked.set()
            s.commit()

    with factory() as holder:
        begin_write(holder)
        lock_system(holder, holder_system)
        thread = threading.Thread(target=second)
        thread.start()
        waited = not locked.wait(0.7)
        holder.commit()
    thread.join(10)
    assert locked.is_set(), "the second edit never went on after the first committed"
    return waited


def test_edits_of_one_system_wait_for_each_other_and_others_do_not(systems) -> None:
    factory, ids = systems
    assert _waits_for(factory, ids["broadcast/1.png"], ids["broadcast/1.png"])
    assert not _waits_for(factory, ids["broadcast/1.png"], ids["broadcast/2.png"])  # a sibling system: at once


def test_edits_of_one_issia_sequence_wait_for_each_other(systems) -> None:
    factory, ids = systems
    assert _waits_for(factory, ids["filmA/0"], ids["filmA/1"])  # a re-fit touches the whole sequence
    assert not _waits_for(factory, ids["filmA/0"], ids["broadcast/1.png"])


def test_locking_a_missing_system_is_not_found(systems) -> None:
    factory, _ = systems
    with factory() as s, pytest.raises(NotFoundError):
        lock_system(s, 10**9)
