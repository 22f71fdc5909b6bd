"""The queue queries (window functions, NULLS LAST, coalesced enum status) on PostgreSQL, which the
rest of the API suite runs on SQLite."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from app.core.config import Settings
from app.db.models import System
from app.db.session import make_engine, make_session_factory, upgrade_database
from app.geometry.calibration.result import MIRROR_FLAG
from app.main import create_app
from app.services.derivation.recompute import update_summary
from tests.accounts import as_token, make_accounts

from .factories import make_game, make_system


def _seed(url: str, settings: Settings, build):
    """Run ``build(session, game)`` in one committed session of the migrated PostgreSQL database ``url``, return its
    result."""
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            out = build(session, make_game(session))
            session.commit()
            return out
    finally:
        engine.dispose()

pytestmark = pytest.mark.postgres


def test_queue_and_system_view_on_postgresql(pg_migrated_url: str) -> None:
    settings = Settings(database_url=pg_migrated_url, calibration_workers=1)

    def build(session, game):
        exact = make_system(session, settings, game, "2.png", jac=0.90).system_id
        shifted = make_system(session, settings, game, "10.png", jac=0.80, shift_px=(0.0, 0.0, 6.0)).system_id
        lonely = make_system(session, settings, game, "1.png", jac=0.95, labelled=(True, False, False)).system_id
        system = session.get(System, lonely)
        system.frames[1].calibration.flags = [MIRROR_FLAG]  # the JSONB flags
        update_summary(system, system.triangulation)  # stored with the flag, as the recomputation does
        return exact, shifted, lonely

    exact, shifted, lonely = _seed(pg_migrated_url, settings, build)
    admin = make_accounts(pg_migrated_url, login=False, roles=("admin",))["admin"]
    with as_token(TestClient(create_app(settings)), admin) as client:
        def ids(**p):
            return [s["id"] for s in client.get("/api/systems", params=p).json()["items"]]
        assert ids(sort="-worst_error") == [shifted, exact, lonely]
        rows = client.get("/api/systems").json()["items"]
        assert set(ids(doubt="any")) == {r["id"] for r in rows if r["label_doubts"]}
        assert set(ids(doubt="none")) == {r["id"] for r in rows if not r["label_doubts"]}
        assert ids(sort="lowest_jac") == [shifted, exact, lonely]
        assert ids(sort="name") == [lonely, exact, shifted]
        assert ids(error_min=1.0) == [shifted]
        flagged_rows = {s["id"]: s["views_flagged"] for s in client.get("/api/systems").json()["items"]}
        assert flagged_rows == {shifted: 0, exact: 0, lonely: 1}
        etag = client.get(f"/api/systems/{exact}").headers["ETag"]  # a token's write names the version it changes
        assert client.post(f"/api/systems/{exact}/review", json={"status": "accepted"},
                           headers={"If-Match": etag}).status_code == 200
        pending = client.get("/api/systems", params={"status": "pending", "sort": "-worst_error"}).json()
        assert [s["id"] for s in pending["items"]] == [shifted, lonely]
        assert pending["counts"] == {"pending": 2, "accepted": 1, "rejected": 0, "needs_fix": 0, "fixed": 0}
        view = client.get(f"/api/systems/{exact}", params={"status": "pending", "sort": "-worst_error"}).json()
        assert (view["prev_id"], view["next_id"]) == (shifted, lonely)
        assert len(view["views"]) == 3 and client.get(view["views"][0]["pitch_lines_url"]).json()["lines"]


def test_views_above_tau_on_postgresql(pg_migrated_url: str) -> None:
    """The queue's ``views_above_tau`` (float reference width, integer width, stored tau) on PostgreSQL,
    and the system view's ``error_above_tau`` by the same rule (the scene of test_systems' count, by class: ball_rule
    "weights", under which the 40 px box's pairs meet as that test says)."""
    settings = Settings(database_url=pg_migrated_url, calibration_workers=1, ball_rule="weights")

    def build(session, game):
        exact = make_system(session, settings, game, "2.png").system_id
        # a box 40 px off: two of the 960-px views above tau once scaled to 1920 px (none raw)
        wrong = make_system(session, settings, game, "4.png", shift_px=(0.0, 0.0, 40.0)).system_id
        return exact, wrong

    exact, wrong = _seed(pg_migrated_url, settings, build)
    admin = make_accounts(pg_migrated_url, login=False, roles=("admin",))["admin"]
    with as_token(TestClient(create_app(settings)), admin) as client:
        rows = {s["id"]: s["views_above_tau"] for s in client.get("/api/systems").json()["items"]}
        assert rows == {exact: 0, wrong: 2}
        view = client.get(f"/api/systems/{wrong}").json()
        assert [v["error_above_tau"] for v in view["views"]] == [True, False, True]


def test_soccernet_v3d_export_on_postgresql(pg_migrated_url: str, tmp_path) -> None:
    """The export reads JSON columns as their text (``jsonb::text`` on PostgreSQL): every cell and
    document value equals the stored one, SQL NULL and JSON null both empty."""
    import csv
    import json

    from app.db.models import Frame
    from app.services.transfer.exporting import export_soccernet_v3d

    settings = Settings(database_url=pg_migrated_url, calibration_workers=1)
    sid = _seed(pg_migrated_url, settings,
                lambda session, game: make_system(session, settings, game, "2.png").system_id)
    engine = make_engine(pg_migrated_url)
    try:
        with make_session_factory(engine)() as session:
            report = export_soccernet_v3d(session, tmp_path, include_all=True)
            frames = {f.name: f for f in session.get(System, sid).frames}
            rows = list(csv.DictReader(report.csv_path.open()))
            assert len(rows) == len(frames) == 3
            doc = json.loads(report.label_files[0].read_text())
            for row in rows:
                frame: Frame = frames[row["action"] == "True" and row["main_action"] or row["replay"]]
                assert json.loads(row["calibration"]) == frame.calibration.camera
                assert json.loads(row["ball_bbox"]) == frame.ball_label.box
                assert json.loads(row["optimized_bbox"]) == frame.optimised_box.box
                assert row["ball_point"] == ""  # a box label: its point is JSON null
                entry = doc["actions"].get(frame.name) or doc["replays"][frame.name]
                assert entry["calibration"] == frame.calibration.camera
                assert entry["v3d"]["flags"] == list(frame.calibration.flags)
    finally:
        engine.dispose()


def test_ids_beyond_32_bits_and_nul_characters_are_422_on_postgresql(pg_migrated_url: str) -> None:
    """Found by benchmarks/fuzz.py --database-url (PostgreSQL): an id beyond the 32-bit INTEGER columns
    ("integer out of range") and a NUL character in text (which PostgreSQL cannot store) were 500s."""
    settings = Settings(database_url=pg_migrated_url, calibration_workers=1)
    system_id = _seed(pg_migrated_url, settings,
                      lambda session, game: make_system(session, settings, game, "2.png").system_id)
    admin = make_accounts(pg_migrated_url, login=False, roles=("admin",))["admin"]
    with as_token(TestClient(create_app(settings)), admin) as client:
        for url, loc in [("/api/systems/2147483648", ["path", "system_id"]),
                         ("/api/frames/99999999999/image", ["path", "frame_id"]),
                         ("/api/systems?game_id=-2147483649", ["query", "game_id"]),
                         ("/api/frames?offset=2147483648", ["query", "offset"])]:
            answer = client.get(url)
            assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == loc, (url, answer.text)
        assert client.get("/api/systems/2147483647").status_code == 404
        etag = client.get(f"/api/systems/{system_id}").headers["ETag"]
        answer = client.post(f"/api/systems/{system_id}/review", json={"status": "accepted", "comment": "a\x00b"},
                             headers={"If-Match": etag})
        assert answer.status_code == 422 and "comment" in answer.json()["detail"][0]["msg"]
        assert client.get(f"/api/systems/{system_id}").json()["review"]["status"] == "pending"  # nothing stored
        answer = client.post("/api/users/a%00b/tokens")
        assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["path", "name"]
    with TestClient(create_app(settings)) as anonymous:
        answer = anonymous.post("/api/auth/login", json={"name": "test-admin\x00", "password": "x"})
        assert answer.status_code == 422 and "name" in answer.json()["detail"][0]["msg"]


def test_connections_run_without_jit_and_migrations_analyse(pg_url: str) -> None:
    """Issue 29: on a database without statistics (autovacuum off or not yet run) the planner's estimates passed
    the JIT threshold and an edit's frames query compiled for about 64 ms; v3d's connections run with JIT off and
    the migrations (as every import) end with ANALYZE, so the tables carry statistics from the start. Options named
    in the URL's query or in ``connect_args`` win (the URL's were replaced by v3d's own until 2026-11-25)."""
    upgrade_database(pg_url)
    engine = make_engine(pg_url)
    try:
        with engine.connect() as conn:
            assert conn.exec_driver_sql("SHOW jit").scalar() == "off"
            analysed = conn.exec_driver_sql(
                "SELECT count(*) FROM pg_stat_user_tables WHERE relname IN ('frames', 'systems') "
                "AND coalesce(last_analyze, last_autoanalyze) IS NOT NULL").scalar()
            assert analysed == 2
    finally:
        engine.dispose()
    explicit = make_engine(pg_url, connect_args={"options": "-c jit=on"})
    try:
        with explicit.connect() as conn:  # an explicit choice in the options wins
            assert conn.exec_driver_sql("SHOW jit").scalar() == "on"
    finally:
        explicit.dispose()
    in_url = make_engine(f"{pg_url}?options=-c%20jit%3Don%20-c%20work_mem%3D8MB", write_lock_timeout_s=2.0)
    try:
        with in_url.connect() as conn:  # so do the URL's options, kept beside v3d's own
            assert conn.exec_driver_sql("SHOW jit").scalar() == "on"
            assert conn.exec_driver_sql("SHOW work_mem").scalar() == "8MB"
            assert conn.exec_driver_sql("SHOW lock_timeout").scalar() == "2s"
    finally:
        in_url.dispose()


def test_statements_stay_prepared_across_requests_that_end_their_reads_by_a_commit(pg_migrated_url: str) -> None:
    """psycopg prepares a statement run 5 times on a connection and forgets them all on a rollback, so a request's
    session ends its read-only transaction by a commit (``app.api.deps.get_session``, ``app.db.session.end_reads``):
    the statements stay prepared from one request to the next; a rollback still discards what a transaction wrote,
    and the pool's reset on return rolls back a transaction left open."""
    import sqlalchemy as sa

    from app.db.models import Game
    from app.db.session import end_reads

    engine = make_engine(pg_migrated_url, pool_size=1, max_overflow=0)  # one connection: every session below shares it
    factory = make_session_factory(engine)
    lookup = sa.select(Game.id).where(Game.match == sa.bindparam("m"))
    try:
        for i in range(7):  # each session ends its reads as a request's does
            with factory() as s:
                assert s.execute(lookup, {"m": f"none-{i}"}).first() is None
                end_reads(s)
        with factory() as s:
            prepared = s.execute(sa.text("SELECT statement FROM pg_prepared_statements")).scalars().all()
            assert any("FROM games" in p and "games.match" in p for p in prepared), prepared
            s.add(Game(league="l", season="s", match="rolled back", source_path="/x"))
            s.flush()
            s.rollback()
            assert s.execute(lookup, {"m": "rolled back"}).first() is None
        raw = engine.raw_connection()  # a connection going back to the pool with its transaction open
        raw.cursor().execute("INSERT INTO games (league, season, match, source_path, created_at) "
                             "VALUES ('l', 's', 'left open', '/x', now())")
        raw.close()  # the pool's reset on return rolls it back
        with factory() as s:
            assert s.execute(lookup, {"m": "left open"}).first() is None
    finally:
        engine.dispose()


def test_a_rollback_on_a_connection_the_server_closed_discards_the_connection(pg_migrated_url: str) -> None:
    """A rollback on a connection the server has closed (a restart, an administrator's ``pg_terminate_backend``)
    raises, so the pool discards that connection, and the next session works on a new one."""
    import time

    import sqlalchemy as sa
    engine = make_engine(pg_migrated_url, pool_size=1, max_overflow=0)
    admin = make_engine(pg_migrated_url, isolation_level="AUTOCOMMIT")
    factory = make_session_factory(engine)
    try:
        s = factory()
        pid = s.execute(sa.text("SELECT pg_backend_pid()")).scalar()
        with admin.connect() as conn:
            assert conn.execute(sa.text("SELECT pg_terminate_backend(:pid)"), {"pid": pid}).scalar()
            # pg_terminate_backend only signals the backend: the rollback must meet a closed connection, so wait
            # until the server no longer lists it (a deadline for a loaded machine)
            deadline = time.monotonic() + 30
            while conn.execute(sa.text("SELECT count(*) FROM pg_stat_activity WHERE pid = :pid"),
                               {"pid": pid}).scalar():
                assert time.monotonic() < deadline, f"backend {pid} still running 30 s after its termination"
                time.sleep(0.02)
        with pytest.raises(sa.exc.OperationalError) as raised:
            s.rollback()
        assert raised.value.connection_invalidated
        s.close()
        with factory() as s:
            assert s.execute(sa.text("SELECT pg_backend_pid()")).scalar() != pid
    finally:
        engine.dispose()
        admin.dispose()
