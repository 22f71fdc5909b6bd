"""The audit log and edit versions in the services: one entry per import and per full recompute (with
its counts), local attribution, append-only storage, non-revertible summaries, versions an import
bumps only when it changes what people edit, and the compare-and-set of two concurrent writers on
PostgreSQL."""
from __future__ import annotations

import threading

import pytest
import sqlalchemy as sa

from app.core.errors import InvalidInputError, StaleVersionError
from app.db.models import AuditEntry, Frame, System
from app.services.audit import log as audit
from app.services.curation import editing
from app.services.curation.reverting import revert_entry
from app.services.derivation.recompute import refresh_stale_systems
from app.services.transfer.importing import import_soccernet_v3

pytestmark = pytest.mark.engine


def _entries(session) -> list[AuditEntry]:
    """The entries of the data's edits, imports and recomputes (the test users' own ``user.create`` entries,
    made once per test session, left out)."""
    return list(session.scalars(sa.select(AuditEntry).where(AuditEntry.action.not_in(audit.ADMIN_ACTIONS))
                                .order_by(AuditEntry.id)))


def test_an_import_is_one_entry_with_its_counts_and_cannot_be_reverted(db_session, settings, v3_tree):
    report = import_soccernet_v3(db_session, v3_tree, settings, actor="admin-ada")
    (entry,) = _entries(db_session)
    assert (entry.action, entry.actor, entry.before, entry.frame_id) == ("import", "admin-ada", None, None)
    assert entry.after == {"source": str(v3_tree), "source_name": "v3", "games": 1, "systems": 3, "frames": 8,
                           "systems_new": 3,
                           "systems_changed": 0, "calibrated": report.calibrated, "refused": report.refused,
                           "triangulated": report.triangulated, "batch": 1, "batches": 1, "batch_games": 1}
    versions = dict(db_session.execute(sa.select(Frame.id, Frame.edit_version)).all())
    assert set(versions.values()) == {1}
    again = import_soccernet_v3(db_session, v3_tree, settings)  # unchanged input: no version moves
    assert again.systems_changed == 0
    entries = _entries(db_session)
    assert [e.action for e in entries] == ["import", "import"] and entries[1].actor == audit.local_actor()
    assert dict(db_session.execute(sa.select(Frame.id, Frame.edit_version)).all()) == versions
    with pytest.raises(InvalidInputError, match="import.*cannot be reverted"):
        revert_entry(db_session, entry.id, settings=settings)


def test_a_full_recompute_is_one_entry(db_session, settings, v3_tree):
    import_soccernet_v3(db_session, v3_tree, settings)
    db_session.execute(sa.update(System).values(derived_version=0))
    db_session.commit()
    assert refresh_stale_systems(db_session, settings) == 3
    entries = _entries(db_session)
    assert [e.action for e in entries] == ["import", "recompute"]
    assert entries[1].after["systems"] == 3 and entries[1].actor.startswith("cli:")
    assert (entries[1].after["batch"], entries[1].after["batches"], entries[1].after["batch_systems"]) == (1, 1, 3)
    # nothing to do: no entry
    assert refresh_stale_systems(db_session, settings) == 0 and len(_entries(db_session)) == 2


def test_every_committed_batch_of_an_import_or_a_recompute_is_an_entry(db_session, settings, shared_dir, tmp_path,
                                                                      monkeypatch):
    """Issue 15: an import or a recompute that committed earlier batches wrote one entry, for the last only, so
    a crash after the first batches left stored games without a trace."""
    from app.services.derivation import recompute
    from tests.services.datasets import write_v3_game

    root = tmp_path / "two"
    write_v3_game(shared_dir, root, game=("league-a", "2020-2021", "game one"))
    write_v3_game(shared_dir, root, game=("league-a", "2020-2021", "game two"))
    import_soccernet_v3(db_session, root, settings.model_copy(update={"import_batch_frames": 1}), actor="ada")
    imports = _entries(db_session)
    assert [(e.action, e.actor, e.after["batch"], e.after["batches"], e.after["batch_games"]) for e in imports] == [
        ("import", "ada", 1, 2, 1), ("import", "ada", 2, 2, 1)]
    assert imports[1].after["games"] == 2 and imports[1].after["systems"] == 6
    monkeypatch.setattr(recompute, "_REFRESH_BATCH", 4)
    recompute.recompute_all_systems(db_session, settings, actor="ada")
    recomputes = [e.after for e in _entries(db_session) if e.action == "recompute"]
    assert [(a["batch"], a["batches"], a["batch_systems"], a["systems"]) for a in recomputes] == [(1, 2, 4, 6),
                                                                                              (2, 2, 2, 6)]


def test_service_edits_are_attributed_to_the_local_user_by_default(db_session, settings, v3_tree):
    import_soccernet_v3(db_session, v3_tree, settings)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "2_1.png")).one()
    box = list(frame.ball_label.box)
    editing.update_ball_label(db_session, frame.id, box=[b + 1.5 for b in box], settings=settings)
    entry = _entries(db_session)[-1]
    assert (entry.actor, entry.action, entry.frame_id, entry.system_id) == (
        audit.local_actor(), "ball.edit", frame.id, frame.system_id)
    assert entry.before == {"ball": {"box": box, "point": None}}
    assert db_session.get(Frame, frame.id).edit_version == 2


def test_a_label_put_back_to_the_imported_one_is_said_restored_not_moved(db_session, settings, v3_tree):
    """The page's ``z`` writes the imported box back: its entry says so; a move that only comes near it, and the undo
    of the restore, read as what they are."""
    import_soccernet_v3(db_session, v3_tree, settings)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "2_1.png")).one()
    box = list(frame.ball_label.box)
    editing.update_ball_label(db_session, frame.id, box=[box[0] + 6, box[1] + 8, box[2] + 6, box[3] + 8],
                              settings=settings)
    assert _entries(db_session)[-1].summary == "ball of V2 moved 10.0 px"
    editing.update_ball_label(db_session, frame.id, box=box, settings=settings)
    restore = _entries(db_session)[-1]
    assert restore.summary == "ball of V2 restored to the imported label", restore.summary
    editing.update_ball_label(db_session, frame.id, box=[box[0] + 1, box[1], box[2] + 1, box[3]], settings=settings)
    assert _entries(db_session)[-1].summary == "ball of V2 moved 1.0 px"


def test_audit_entries_are_append_only(db_session, settings, v3_tree):
    import_soccernet_v3(db_session, v3_tree, settings)
    for statement in ("UPDATE audit_entries SET actor = 'mallory'", "DELETE FROM audit_entries"):
        with pytest.raises(sa.exc.DatabaseError, match="append-only"):
            with db_session.begin_nested():
                db_session.execute(sa.text(statement))
    assert [e.actor for e in _entries(db_session)] == [audit.local_actor()]


def test_a_stale_expected_version_changes_nothing(db_session, settings, v3_tree):
    import_soccernet_v3(db_session, v3_tree, settings)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "2_1.png")).one()
    box = list(frame.ball_label.box)
    editing.update_ball_label(db_session, frame.id, box=[b + 2 for b in box], settings=settings, expected={1})
    with pytest.raises(StaleVersionError) as caught:
        editing.update_ball_label(db_session, frame.id, box=[b - 2 for b in box], settings=settings, expected={1})
    assert caught.value.etag == f'"frame-{frame.id}-2"'
    assert caught.value.current.id == frame.id and caught.value.current.ball_label.box == [b + 2 for b in box]
    assert caught.value.last_change.action == "ball.edit"
    db_session.expire_all()
    assert db_session.get(Frame, frame.id).ball_label.box == [b + 2 for b in box]
    assert len(_entries(db_session)) == 2


@pytest.mark.parametrize("returning", [True, False])
def test_a_claim_reads_its_new_version_with_or_without_returning(db_session, settings, v3_tree, monkeypatch,
                                                                  returning):
    """The claim reads the frame's new version from its ``UPDATE ... RETURNING``; a database without RETURNING
    (SQLite before 3.35) reads it with a SELECT: the same versions, ETags and refusals either way."""
    import_soccernet_v3(db_session, v3_tree, settings)
    monkeypatch.setattr(db_session.get_bind().dialect, "update_returning", returning)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "2_1.png")).one()
    fid, box = frame.id, list(frame.ball_label.box)
    editing.update_ball_label(db_session, fid, box=[b + 2 for b in box], settings=settings, expected={1})
    assert db_session.get(Frame, fid).edit_version == 2
    editing.update_ball_label(db_session, fid, box=[b + 3 for b in box], settings=settings, expected={2})
    with pytest.raises(StaleVersionError) as caught:
        editing.update_ball_label(db_session, fid, box=[b - 2 for b in box], settings=settings, expected={2})
    assert caught.value.etag == f'"frame-{fid}-3"'
    db_session.expire_all()
    assert db_session.get(Frame, fid).edit_version == 3
    assert db_session.get(Frame, fid).ball_label.box == [b + 3 for b in box]


@pytest.mark.postgres
def test_two_writers_with_the_same_version_on_postgres_one_wins(pg_migrated_url, settings, v3_tree):
    """Writer A locks the system, bumps the frame's and the system's versions and holds its transaction open; writer
    B, with the same expected version, waits on the row lock, then finds the version moved: 412 for B, A's edit
    stored, one entry."""
    from app.db.session import begin_write, make_engine, make_session_factory
    from app.services.curation.writing import lock_system
    engine = make_engine(pg_migrated_url)
    try:
        factory = make_session_factory(engine)
        with factory() as setup:
            import_soccernet_v3(setup, v3_tree, settings)
            fid = setup.scalars(sa.select(Frame.id).where(Frame.name == "2_2.png")).one()
        a, b = factory(), factory()
        begin_write(a)
        lock_system(a, a.get(Frame, fid).system_id, game=True)  # A holds the lock, as an edit's write does
        frame = a.get(Frame, fid)
        frame.edit_version += 1
        frame.system.version += 1
        a.flush()
        outcome: dict[str, object] = {}

        def writer_b() -> None:
            try:
                editing.set_view_excluded(b, fid, True, settings=settings, actor="b", expected={1})
                outcome["b"] = "stored"
            except StaleVersionError as exc:
                outcome["b"] = exc.etag

        thread = threading.Thread(target=writer_b)
        thread.start()
        thread.join(timeout=1.0)
        assert thread.is_alive(), "B did not wait for A's lock"
        a.commit()
        thread.join(timeout=30)
        assert outcome == {"b": f'"frame-{fid}-2"'}
        a.close()
        b.close()
        with factory() as check:
            assert check.get(Frame, fid).edit_version == 2
            assert check.scalar(sa.select(sa.func.count()).select_from(AuditEntry)
                                .where(AuditEntry.frame_id == fid)) == 0  # A claimed only; B refused
    finally:
        engine.dispose()


@pytest.mark.postgres
def test_audit_entries_are_append_only_on_postgres_and_the_migration_goes_both_ways(pg_migrated_url):
    from alembic import command

    from app.db.session import alembic_config, make_engine, upgrade_database
    engine = make_engine(pg_migrated_url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("INSERT INTO audit_entries (at, actor, action) VALUES (now(), 'ada', 'import')"))
        for statement in ("UPDATE audit_entries SET actor = 'mallory'", "DELETE FROM audit_entries"):
            with pytest.raises(sa.exc.DatabaseError, match="append-only"):
                with engine.begin() as conn:
                    conn.execute(sa.text(statement))
        with engine.connect() as conn:
            assert conn.execute(sa.text("SELECT actor FROM audit_entries")).scalars().all() == ["ada"]
    finally:
        engine.dispose()
    command.downgrade(alembic_config(pg_migrated_url), "-1")  # 0006 alone
    upgrade_database(pg_migrated_url)
    command.check(alembic_config(pg_migrated_url))
