"""Write transactions of several processes on one database (issue 7): ``begin_write`` takes SQLite's
write lock before the unit of work reads (``BEGIN IMMEDIATE``) and waits its turn, reads stay deferred
and never wait, and a read-only transaction is ended (its objects read again) rather than upgraded.
Two engines on one file stand for two server processes."""
from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db.models import Game
from app.db.session import begin_write, make_engine, make_session_factory
from tests.conftest import migrate_new_database

pytestmark = pytest.mark.engine


@pytest.fixture
def two_processes(tmp_path: Path):
    """Two engines (as two server processes would have) on one migrated SQLite file holding one game,
    the second with a 0.3 s busy timeout; yields ``(factory_a, factory_b, game_id)``."""
    url = f"sqlite:///{tmp_path / 'shared.sqlite3'}"
    migrate_new_database(url)
    a = make_engine(url)
    b = make_engine(url, connect_args={"timeout": 0.3})
    with make_session_factory(a)() as s:
        game = Game(league="l", season="s", match="before", source_path="/x")
        s.add(game)
        s.commit()
        game_id = game.id
    yield make_session_factory(a), make_session_factory(b), game_id
    a.dispose()
    b.dispose()


def test_a_write_transaction_holds_the_lock_from_its_start_and_the_next_waits_its_turn(two_processes) -> None:
    fa, fb, game_id = two_processes
    with fa() as a, fb() as b:
        begin_write(a)  # BEGIN IMMEDIATE: the write lock before anything is read
        a.get(Game, game_id).match = "by a"
        a.flush()
        assert b.get(Game, game_id).match == "before"  # a reader does not wait (WAL) and sees the last commit
        b.rollback()
        t0 = time.monotonic()
        with pytest.raises(sa.exc.OperationalError, match="database is locked"):
            begin_write(b)  # waits the busy timeout for the writer, then gives up
        assert time.monotonic() - t0 >= 0.25
        b.rollback()

        done = threading.Event()

        def second_writer() -> None:
            with fa() as c:  # the long busy timeout: waits for a to commit
                begin_write(c)
                game = c.get(Game, game_id)
                game.match = game.match + ", then c"  # read-modify-write under the lock
                c.commit()
            done.set()

        thread = threading.Thread(target=second_writer)
        thread.start()
        assert not done.wait(0.5)  # c waits its turn
        a.commit()
        thread.join(10)
        assert done.is_set()
    with fa() as s:
        assert s.get(Game, game_id).match == "by a, then c"  # nothing lost


def test_begin_write_ends_a_read_transaction_and_reads_again_under_the_lock(two_processes) -> None:
    fa, fb, game_id = two_processes
    with fa() as reader, fb() as other:
        game = reader.get(Game, game_id)  # a deferred read transaction (an API request's lookup)
        assert game.match == "before"
        begin_write(other)
        other.get(Game, game_id).match = "changed meanwhile"
        other.commit()
        begin_write(reader)  # ends the stale read transaction: no upgrade, no "database is locked"
        assert game.match == "changed meanwhile"  # expired, read again under the write lock
        game.match += ", edited"
        reader.commit()
        begin_write(reader)
        begin_write(reader)  # the same write transaction: nothing happens
        assert reader.get(Game, game_id).match == "changed meanwhile, edited"


def test_begin_write_refuses_changes_made_after_reading_without_the_lock(two_processes) -> None:
    """Changes made in a transaction that read without the write lock are refused (they were computed from a read
    that no lock protects); changes made in memory with no read since the last transaction ended (an edit computed
    after its reads) are kept, for the write transaction to flush."""
    fa, _, game_id = two_processes
    with fa() as s:
        s.get(Game, game_id).match = "pending"
        with pytest.raises(RuntimeError, match="no write lock"):
            begin_write(s)
        s.rollback()
    with fa() as s:
        game = s.get(Game, game_id)
        s.commit()  # the reads ended, the object kept (expire_on_commit off)
        game.match = "computed in memory"
        begin_write(s)
        s.commit()
    with fa() as s:
        assert s.get(Game, game_id).match == "computed in memory"


def test_begin_write_leaves_a_joined_external_transaction_alone(db_connection: sa.Connection) -> None:
    session = Session(bind=db_connection, join_transaction_mode="create_savepoint")
    session.add(Game(league="l", season="s", match="joined", source_path="/x"))
    session.flush()
    begin_write(session)  # the caller owns the transaction: no rollback, no error
    assert session.scalar(sa.select(sa.func.count()).where(Game.match == "joined")) == 1
    session.close()


def test_end_reads_refuses_a_transaction_that_flushed_outside_a_write_unit(two_processes) -> None:
    """A change flushed in a read transaction (an autoflush before a query, or an explicit flush) is no read: ending
    the reads must not commit it, which would write without the write unit's lock, version check and audit."""
    from app.db.session import end_reads

    fa, fb, game_id = two_processes
    with fa() as a:
        a.get(Game, game_id).match = "flushed, never meant to be written"
        a.scalars(sa.select(Game)).all()  # autoflush: the UPDATE is sent in the read transaction
        with pytest.raises(RuntimeError, match="flushed changes outside a write unit"):
            end_reads(a)
        a.rollback()
    with fb() as b:
        assert b.get(Game, game_id).match == "before"
    with fa() as a:  # a transaction that only read still ends with a commit (its objects kept)
        game = a.get(Game, game_id)
        end_reads(a)
        assert not a.in_transaction() and game.match == "before"


def test_only_v3ds_sessions_note_their_flushes(two_processes) -> None:
    """The flush listeners behind :func:`end_reads` are v3d's sessions' alone: a plain SQLAlchemy ``Session`` of the
    same process (another library's) flushes with its ``info`` left as it was."""
    fa, _fb, game_id = two_processes
    with Session(fa.kw["bind"]) as other:
        other.get(Game, game_id).match = "another library's flush"
        other.flush()
        assert other.info == {}
        other.rollback()
    with fa() as a:
        a.get(Game, game_id).match = "v3d's flush"
        a.flush()
        assert a.info == {"v3d_flushed": True}
        a.rollback()
        assert a.info == {}
