"""The schema is built by Alembic, matches the models (``alembic check``), and migrates both ways,
on SQLite always and on the local PostgreSQL when it runs."""
from __future__ import annotations

import warnings

import pytest
import sqlalchemy as sa
from alembic import command
from sqlalchemy.exc import SAWarning

from app.db.models import Base
from app.db.session import alembic_config, make_engine, upgrade_database

pytestmark = pytest.mark.engine


def test_upgrade_then_check_on_sqlite(tmp_path):
    url = f"sqlite:///{tmp_path / 'nested' / 'm.sqlite3'}"
    upgrade_database(url)  # also creates the missing parent folder
    command.check(alembic_config(url))  # raises when the models and the migrations disagree
    engine = make_engine(url)
    try:
        tables = set(sa.inspect(engine).get_table_names())
    finally:
        engine.dispose()
    assert set(Base.metadata.tables) <= tables
    assert "alembic_version" in tables


def test_a_start_on_a_new_database_warns_nothing(tmp_path):
    """What ``v3d serve`` does at its start (migrate a new database, then again at the next start, build the app)
    raises no SQLAlchemy warning: a batch rebuild reflects only its own table, never the systems table whose
    expression index SQLite's reflection skips with a warning."""
    from app.core.config import Settings
    from app.main import create_app

    url = f"sqlite:///{tmp_path / 'start.sqlite3'}"
    with warnings.catch_warnings():
        warnings.simplefilter("error", SAWarning)
        upgrade_database(url)
        upgrade_database(url)
        create_app(Settings(database_url=url))


def test_downgrade_to_base_and_up_again(tmp_path):
    url = f"sqlite:///{tmp_path / 'm.sqlite3'}"
    upgrade_database(url)
    command.downgrade(alembic_config(url), "base")
    engine = make_engine(url)
    try:
        assert set(sa.inspect(engine).get_table_names()) == {"alembic_version"}
    finally:
        engine.dispose()
    upgrade_database(url)
    command.check(alembic_config(url))


def test_sqlite_engine_enforces_foreign_keys_and_uses_wal(db_engine, db_backend):
    if db_backend != "sqlite":
        pytest.skip("SQLite pragmas: the suite runs on PostgreSQL (V3D_TEST_DATABASE_URL)")
    with db_engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"


@pytest.mark.postgres
def test_upgrade_then_check_on_postgres(pg_url):
    upgrade_database(pg_url)
    command.check(alembic_config(pg_url))
    engine = make_engine(pg_url)
    try:
        cols = {c["name"]: c for c in sa.inspect(engine).get_columns("calibrations")}
    finally:
        engine.dispose()
    assert type(cols["camera"]["type"]).__name__ == "JSONB"
    assert type(cols["jac_0005"]["type"]).__name__ == "DOUBLE_PRECISION"


@pytest.mark.processes
def test_alembic_command_line_takes_the_url_from_the_settings(tmp_path):
    """``alembic upgrade head`` then ``alembic check``, as CI runs them, with ``V3D_DATABASE_URL``."""
    import os
    import subprocess
    import sys

    from app.core.paths import PROJECT_ROOT

    db = tmp_path / "cli.sqlite3"
    env = {**os.environ, "V3D_DATABASE_URL": f"sqlite:///{db}"}
    alembic = [sys.executable, "-m", "alembic", "-c", str(PROJECT_ROOT / "alembic.ini")]
    for args in (["upgrade", "head"], ["check"]):
        done = subprocess.run(alembic + args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
    assert "No new upgrade operations detected" in done.stdout + done.stderr
    assert db.is_file()


def test_upgrading_a_filled_sqlite_database_keeps_every_row(tmp_path):
    """Regression: migration 0003 rebuilds ``systems`` (SQLite batch mode: copy, drop, rename); with
    foreign keys on, dropping the parent table cascaded to every frame and review, so upgrading a filled
    database emptied it. Migrations now run with foreign keys off, then check them."""
    url = f"sqlite:///{tmp_path / 'filled.sqlite3'}"
    upgrade_database(url, "0002")
    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("INSERT INTO games (id, league, season, match, source_path, created_at) "
                                 "VALUES (1, 'l', 's', 'm', '/x', '2026-01-01 00:00:00')"))
            conn.execute(sa.text("INSERT INTO systems (id, game_id, name, kind, created_at) "
                                 "VALUES (1, 1, '1.png', 'soccernet-v3', '2026-01-01 00:00:00')"))
            for i, role in ((1, "action"), (2, "replay")):
                conn.execute(sa.text("INSERT INTO frames (id, system_id, name, role, position, width, height) "
                                     f"VALUES ({i}, 1, '1_{i}.png', '{role}', {i}, 960, 540)"))
            conn.execute(sa.text("INSERT INTO review_decisions (id, system_id, status, comment) "
                                 "VALUES (1, 1, 'accepted', 'ok')"))
    finally:
        engine.dispose()
    upgrade_database(url)
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            assert conn.execute(sa.text("SELECT count(*) FROM frames")).scalar() == 2
            assert conn.execute(sa.text("SELECT status FROM review_decisions")).scalar() == "accepted"
            row = conn.execute(sa.text("SELECT derived_version, review_status FROM systems")).one()
            assert tuple(row) == (0, "pending")  # stale: recomputed (status copied) before it is served
            assert conn.execute(sa.text("PRAGMA foreign_keys")).scalar() == 1
        from app.core.config import Settings
        from app.db.models import System
        from app.db.session import make_session_factory
        from app.services.derivation.recompute import refresh_stale_systems

        with make_session_factory(engine)() as session:
            assert refresh_stale_systems(session, Settings(database_url=url)) == 1
            system = session.get(System, 1)
            assert (system.review_status.value, system.views_total, len(system.frames)) == ("accepted", 2, 2)
    finally:
        engine.dispose()


def test_0009_turns_stored_image_paths_into_the_dataset_folder_and_a_relative_path(tmp_path):
    """Issue 15, item 1: rows stored before 0009 held absolute paths; they become the game's folder (or the
    file's folder) plus a relative path, and the downgrade joins them again."""
    url = f"sqlite:///{tmp_path / 'images.sqlite3'}"
    upgrade_database(url, "0008")
    engine = make_engine(url)
    rows = {1: ("/data/l/s/g/Frames-v3.zip", "0.png", None), 2: (None, None, "/data/l/s/g/Frames-v3/1.png"),
            3: (None, None, "/etc/passwd"), 4: (None, None, None)}
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("INSERT INTO games (id, league, season, match, source_path, created_at) "
                                 "VALUES (1, 'l', 's', 'g', '/data/l/s/g', '2026-01-01 00:00:00')"))
            conn.execute(sa.text("INSERT INTO systems (id, game_id, name, kind, created_at) "
                                 "VALUES (1, 1, '0.png', 'soccernet-v3', '2026-01-01 00:00:00')"))
            for i, (z, m, p) in rows.items():
                conn.execute(sa.text("INSERT INTO frames (id, system_id, name, role, position, width, height, "
                                     "image_zip, image_member, image_path) VALUES "
                                     "(:i, 1, :n, 'replay', :i, 960, 540, :z, :m, :p)"),
                             {"i": i, "n": f"{i}.png", "z": z, "m": m, "p": p})
    finally:
        engine.dispose()
    upgrade_database(url, "0009")
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            got = {r[0]: tuple(r[1:]) for r in conn.execute(sa.text(
                "SELECT id, image_root, image_zip, image_member, image_path, image_type FROM frames"))}
    finally:
        engine.dispose()
    assert got == {1: ("/data/l/s/g", "Frames-v3.zip", "0.png", None, None),
                   2: ("/data/l/s/g", None, None, "Frames-v3/1.png", None),
                   3: ("/etc", None, None, "passwd", None),  # kept, but no longer served: not an image
                   4: (None, None, None, None, None)}
    command.downgrade(alembic_config(url), "0008")
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            back = {r[0]: tuple(r[1:]) for r in conn.execute(sa.text(
                "SELECT id, image_zip, image_member, image_path FROM frames"))}
    finally:
        engine.dispose()
    assert back == rows


@pytest.mark.parametrize("backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def test_0024_moves_large_audit_states_into_audit_states_and_back(tmp_path, request, backend):
    """An audit entry stored before 0024 with a large state (field lines) keeps reading the same after the upgrade,
    which stores the state once, compressed, and leaves a small one inline; the downgrade puts it back. The entries'
    append-only triggers hold again afterwards."""
    import json

    url = f"sqlite:///{tmp_path / 'audit.sqlite3'}" if backend == "sqlite" else request.getfixturevalue("pg_url")
    upgrade_database(url, "0023")
    lines = {"lines": {"Middle line": [[[i + 0.123456789, 2 * i + 0.5] for i in range(200)]]}}
    small = {"ball": {"box": [1.0, 2.0, 3.0, 4.0], "point": None}}
    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            for i, (before, after) in enumerate(((lines, lines), (small, small), (lines, small)), start=1):
                conn.execute(sa.text("INSERT INTO audit_entries (id, at, actor, action, before, after) VALUES "
                                     "(:i, '2026-01-01 00:00:00+00', 'ana', 'field_lines.replace', "
                                     + ("CAST(:b AS JSONB), CAST(:a AS JSONB))" if backend == "postgresql"
                                        else ":b, :a)")),
                             {"i": i, "b": json.dumps(before), "a": json.dumps(after)})
    finally:
        engine.dispose()
    upgrade_database(url)
    engine = make_engine(url)
    try:
        from app.db.models import AuditEntry
        from app.db.session import make_session_factory

        with make_session_factory(engine)() as session:
            entries = {e.id: e for e in session.scalars(sa.select(AuditEntry))}
            assert [(entries[i].before, entries[i].after) for i in (1, 2, 3)] == [(lines, lines), (small, small),
                                                                                  (lines, small)]
            assert entries[1].before_inline is None and entries[1].before_digest == entries[3].before_digest
            assert entries[2].before_inline == small and entries[2].before_digest is None
        with engine.connect() as conn:
            assert conn.execute(sa.text("SELECT count(*) FROM audit_states")).scalar() == 1
            with pytest.raises(sa.exc.DatabaseError, match="append-only"):
                conn.execute(sa.text("UPDATE audit_entries SET actor = 'eve'"))
            conn.rollback()
            with pytest.raises(sa.exc.DatabaseError, match="append-only"):
                conn.execute(sa.text("DELETE FROM audit_states"))
    finally:
        engine.dispose()
    command.downgrade(alembic_config(url), "0023")
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(sa.text("SELECT id, before, after FROM audit_entries ORDER BY id")).all()
            as_json = [tuple(json.loads(v) if isinstance(v, str) else v for v in r[1:]) for r in rows]
            assert as_json == [(lines, lines), (small, small), (lines, small)]
            with pytest.raises(sa.exc.DatabaseError, match="append-only"):
                conn.execute(sa.text("DELETE FROM audit_entries"))
    finally:
        engine.dispose()


@pytest.mark.parametrize("backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def test_0029_stores_release_documents_as_gzip_members_and_back(tmp_path, request, backend):
    """A release document stored before 0029 (a zlib stream) is a gzip member of the same canonical JSON after the
    upgrade (what a release's export lays one after another as its documents.jsonl.gz), a zlib stream again after the
    downgrade; the append-only triggers refuse an UPDATE again after each."""
    import gzip
    import zlib

    url = f"sqlite:///{tmp_path / 'release.sqlite3'}" if backend == "sqlite" else request.getfixturevalue("pg_url")
    upgrade_database(url, "0028")
    documents = [b'{"game_id":1,"league":"a"}', b'{"frames":[],"system_id":7}']
    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            for k, doc in enumerate(documents):
                conn.execute(sa.text("INSERT INTO release_documents (digest, body) VALUES (:d, :b)"),
                             {"d": f"{k:064x}", "b": zlib.compress(doc, 6)})
    finally:
        engine.dispose()

    def bodies() -> list[bytes]:
        eng = make_engine(url)
        try:
            with eng.connect() as conn:
                rows = conn.execute(sa.text("SELECT body FROM release_documents ORDER BY digest"))
                found = [bytes(b) for (b,) in rows]
                with pytest.raises(sa.exc.DatabaseError, match="append-only"):
                    conn.execute(sa.text("UPDATE release_documents SET body = body"))
                return found
        finally:
            eng.dispose()

    upgrade_database(url)
    stored = bodies()
    assert all(b.startswith(b"\x1f\x8b") for b in stored)
    assert gzip.decompress(b"".join(stored)) == b"".join(documents)  # members laid one after another: one gzip file
    command.downgrade(alembic_config(url), "0028")
    assert [zlib.decompress(b) for b in bodies()] == documents


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_0031_keys_existing_names_keeping_them_and_both_of_a_colliding_pair(tmp_path, request, backend):
    """Names stored before 0031 keep their names and get their key; two that read as one (made before the rule) both
    stay, the later one's key suffixed with its id; the key's unique index then refuses a third; releases stay
    append-only; the downgrade drops the keys."""
    url = f"sqlite:///{tmp_path / 'names.sqlite3'}" if backend == "sqlite" else request.getfixturevalue("pg_url")
    upgrade_database(url, "0029")
    engine = make_engine(url)
    release = ("INSERT INTO releases (name, note, created_at, created_by, systems, views, hash) "
               "VALUES (:n, '', CURRENT_TIMESTAMP, 'x', 0, 0, '')")
    user = "INSERT INTO users (name, role, password_hash, created_at, disabled, demo, session_generation) " \
           "VALUES (:n, 'annotator', 'x', CURRENT_TIMESTAMP, false, false, 0)"
    try:
        with engine.begin() as conn:
            for name in ("v1", "Cafe\u0301", "V1", "caf\u00e9"):
                conn.execute(sa.text(release), {"n": name})
            for name in ("ana", "Ana", "bob"):
                conn.execute(sa.text(user), {"n": name})
    finally:
        engine.dispose()
    upgrade_database(url)
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            releases = conn.execute(sa.text("SELECT id, name, name_key FROM releases ORDER BY id")).all()
            assert [(r.name, r.name_key) for r in releases] == [
                ("v1", "v1"), ("Cafe\u0301", "caf\u00e9"), ("V1", f"v1#{releases[2].id}"),
                ("caf\u00e9", f"caf\u00e9#{releases[3].id}")]
            users = conn.execute(sa.text("SELECT id, name, name_key FROM users ORDER BY id")).all()
            assert [(u.name, u.name_key) for u in users] == [("ana", "ana"), ("Ana", f"ana#{users[1].id}"),
                                                             ("bob", "bob")]
            with pytest.raises(sa.exc.DatabaseError, match="append-only"):
                conn.execute(sa.text("UPDATE releases SET note = 'changed'"))
            conn.rollback()
            with pytest.raises(sa.exc.IntegrityError):
                conn.execute(sa.text("INSERT INTO users (name, name_key, role, password_hash, created_at, disabled, "
                                     "demo, session_generation) VALUES ('BOB', 'bob', 'annotator', 'x', "
                                     "CURRENT_TIMESTAMP, false, false, 0)"))
    finally:
        engine.dispose()
    command.downgrade(alembic_config(url), "0029")
    engine = make_engine(url)
    try:
        assert "name_key" not in {c["name"] for c in sa.inspect(engine).get_columns("releases")}
    finally:
        engine.dispose()
