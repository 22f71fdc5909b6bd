"""``app.db.together.send_together``: statements of one transaction sent in one round trip on PostgreSQL answer what
SQLAlchemy's ``Connection.execute`` answers for each (rows with values converted by their types, rows matched by an
UPDATE run for several parameter sets), fail as it fails, and read, after a row lock queued before them, what the
database holds once the lock is granted."""
from __future__ import annotations

import threading
import time

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db.models import Frame, FrameRole, Game, System, SystemKind
from app.db.session import is_lock_timeout, make_engine, make_session_factory, upgrade_database
from app.db.together import Call, driver_statement, send_together


def _game_with_frames(session: Session) -> tuple[int, int, list[int]]:
    game = Game(league="l", season="s", match="m", source_path="/x")
    system = System(game=game, name="sys", kind=SystemKind.SOCCERNET_V3)
    session.add_all([game, system])
    for i, role in enumerate([FrameRole.ACTION, FrameRole.REPLAY, FrameRole.REPLAY]):
        session.add(Frame(system=system, name=f"f{i}", role=role, width=1920, height=1080))
    session.flush()
    return game.id, system.id, [f.id for f in system.frames]


_ROWS = sa.select(Frame.id, Frame.role, Frame.width).where(Frame.system_id == sa.bindparam("sid")).order_by(Frame.id)
_WIDTH = sa.update(Frame).where(Frame.id == sa.bindparam("fid")).values(width=sa.bindparam("w"))


def test_answers_as_connection_execute_does(db_session: Session) -> None:
    game_id, sid, fids = _game_with_frames(db_session)
    expected = [tuple(r) for r in db_session.execute(_ROWS, {"sid": sid}).all()]
    assert [r[1] for r in expected] == [FrameRole.ACTION, FrameRole.REPLAY, FrameRole.REPLAY]
    answers = send_together(db_session, [
        Call(_ROWS, {"sid": sid}),
        Call(_WIDTH, [{"fid": fids[0], "w": 1280}, {"fid": fids[1], "w": 1280}, {"fid": -1, "w": 1}]),
        Call(_ROWS, {"sid": sid}),
    ])
    assert answers[0] == expected  # the enum converted as SQLAlchemy converts it
    assert answers[1] == 2  # rows matched in all: the third parameter set names no frame
    assert [r[2] for r in answers[2]] == [1280, 1280, 1920]  # the later statement reads the earlier one's update
    assert send_together(db_session, []) == []


def test_an_update_returning_answers_its_rows_converted_and_a_claim_sent_together_settles(db_session: Session) -> None:
    """An ``UPDATE ... RETURNING`` answers its returned rows, converted by their types (the role back as the enum);
    the claim of a frame's version sent with other calls (``versions.Claim.call``) bumps it and settles as the claim
    run at once does, and a stale one raises the same 412 error."""
    from app.core.errors import StaleVersionError
    from app.services.curation.versions import Claim

    _, sid, fids = _game_with_frames(db_session)
    back = sa.update(Frame).where(Frame.id == sa.bindparam("fid")).values(width=640).returning(Frame.role, Frame.width)
    dialect = db_session.get_bind().dialect
    claim = Claim.frame(fids[0], {1, 7})
    answers = send_together(db_session, [Call(back, {"fid": fids[1]}), claim.call(dialect)])
    assert answers == [[(FrameRole.REPLAY, 640)], [(2,)]]
    claim.settle(db_session, answers[1], expire=False)
    assert db_session.get(Frame, fids[0]).edit_version == 2
    stale = Claim.frame(fids[0], {1})
    answer = send_together(db_session, [stale.call(dialect)])[0]
    assert answer == []
    with pytest.raises(StaleVersionError) as caught:
        stale.settle(db_session, answer)
    assert caught.value.etag == f'"frame-{fids[0]}-2"'


def test_driver_statement_converts_parameters_by_their_types(db_session: Session) -> None:
    """JSON documents and enums are sent as SQLAlchemy sends them (the statement's own literals filled in)."""
    stmt = sa.select(Frame.id).where(Frame.role == sa.bindparam("role", type_=Frame.role.type), Frame.width > 100)
    from sqlalchemy.dialects.postgresql.psycopg import PGDialect_psycopg

    _game_with_frames(db_session)
    ds = driver_statement(stmt, PGDialect_psycopg())
    params = ds.params({"role": FrameRole.ACTION})
    assert sorted(map(str, params.values())) == ["100", "action"]  # the enum by value; the literal built in
    assert "%(role)s" in ds.sql
    with pytest.raises(ValueError, match="positional"):
        driver_statement(stmt, sa.create_engine("sqlite://").dialect)
    assert len(send_together(db_session, [Call(stmt, {"role": FrameRole.ACTION})])[0]) >= 1


def test_a_lock_timeout_fails_as_connection_execute_fails_and_later_reads_see_the_committed_row(pg_url: str) -> None:
    """PostgreSQL: a lock queued before a read in the same round trip makes the read wait for it and then see what
    the holder committed (READ COMMITTED, a snapshot per statement); a lock waited for past ``lock_timeout`` raises
    SQLAlchemy's ``OperationalError`` that ``is_lock_timeout`` recognises, as ``Connection.execute`` would."""
    upgrade_database(pg_url)
    engine = make_engine(pg_url, write_lock_timeout_s=2.0)
    factory = make_session_factory(engine)
    with factory() as s:
        game_id, sid, fids = _game_with_frames(s)
        s.commit()
    lock = sa.select(System.id).where(System.id == sa.bindparam("sid")).with_for_update()
    width = sa.select(Frame.width).where(Frame.id == sa.bindparam("fid"))
    held, release = threading.Event(), threading.Event()

    def holder() -> None:
        with factory() as h:
            h.execute(lock, {"sid": sid})
            h.execute(sa.update(Frame).where(Frame.id == fids[0]).values(width=640))
            held.set()
            release.wait(5)
            h.commit()

    t = threading.Thread(target=holder)
    t.start()
    held.wait(5)
    try:
        with factory() as s:
            threading.Timer(0.3, release.set).start()
            t0 = time.monotonic()
            _, rows = send_together(s, [Call(lock, {"sid": sid}), Call(width, {"fid": fids[0]})])
            assert time.monotonic() - t0 >= 0.25 and rows == [(640,)]  # waited, then read the holder's commit
            s.rollback()
    finally:
        release.set()
        t.join()
    fast = make_session_factory(make_engine(pg_url, write_lock_timeout_s=0.2))
    with factory() as h, fast() as s:
        h.execute(lock, {"sid": sid})
        with pytest.raises(sa.exc.OperationalError) as info:
            send_together(s, [Call(lock, {"sid": sid}), Call(width, {"fid": fids[0]})])
        assert is_lock_timeout(info.value)
        s.rollback()
        h.rollback()
    engine.dispose()


def _round_trips(raw, run) -> tuple[int, list[str]]:
    """The round trips ``run()`` makes on the psycopg connection ``raw`` (libpq's protocol trace: a ``Sync``, or a
    simple ``Query``, waits for the server once) and the statements it parsed."""
    import tempfile

    with tempfile.TemporaryFile("w+") as f:
        raw.pgconn.trace(f.fileno())
        try:
            run()
        finally:
            raw.pgconn.untrace()
        f.seek(0)
        lines = [line.split("\t") for line in f.read().splitlines()]
    sent = [line for line in lines if len(line) > 3 and line[1] == "F"]
    parsed = [line[4].split('"')[3] for line in sent if line[3] == "Parse"]
    return sum(line[3] in ("Sync", "Query") for line in sent), parsed


def test_a_pipeline_that_opens_its_transaction_sends_its_begin_with_it(pg_url: str) -> None:
    """PostgreSQL: a pipeline on an idle connection sends the transaction's ``BEGIN`` (at the session's isolation
    level) with its statements, one round trip in all, where psycopg's implicit ``BEGIN`` would wait for its own
    answer first; the statements still form one transaction (a rollback undoes them, a commit keeps them), and the
    connection's next transaction begins implicitly again, also after a rollback."""
    upgrade_database(pg_url)
    engine = make_engine(pg_url)
    factory = make_session_factory(engine)
    with factory() as s:
        game_id, sid, fids = _game_with_frames(s)
        s.commit()
    with factory() as s:
        raw = s.connection().connection.dbapi_connection
        trips, parsed = _round_trips(raw, lambda: send_together(s, [Call(_WIDTH, {"fid": fids[0], "w": 800}),
                                                                      Call(_ROWS, {"sid": sid})]))
        assert trips == 1 and parsed[0] == "BEGIN" and len(parsed) == 3
        s.rollback()
        assert s.scalar(sa.select(Frame.width).where(Frame.id == fids[0])) == 1920  # the rollback undid the update
        assert raw.autocommit is False  # this read began its transaction implicitly
        s.rollback()
        s.connection(execution_options={"isolation_level": "REPEATABLE READ"})
        trips, parsed = _round_trips(raw, lambda: send_together(s, [Call(_WIDTH, {"fid": fids[0], "w": 800})]))
        assert trips == 1 and parsed[0] == "BEGIN ISOLATION LEVEL REPEATABLE READ"
        s.commit()
        assert raw.autocommit is False
        s.execute(sa.update(Frame).where(Frame.id == fids[1]).values(width=700))  # an implicit transaction again
        s.rollback()
    with factory() as s:
        assert s.scalars(sa.select(Frame.width).where(Frame.id.in_(fids[:2])).order_by(Frame.id)).all() == [800, 1920]
    engine.dispose()
