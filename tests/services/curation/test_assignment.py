"""Work assignment and presence (issue 28, item 10): ``app.services.curation.assignment`` and ``presence``, on
SQLite and (``V3D_TEST_DATABASE_URL``) PostgreSQL, with the clock passed in."""
from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import ConflictError, InvalidInputError, NotFoundError
from app.db.models import AuditEntry, Doubt, Game, ReviewStatus, System, SystemKind, SystemPresence, User, UserRole
from app.services.curation import assignment, presence, queue
from app.services.curation.queue import SystemFilters
from app.services.curation.reverting import revert_entry

pytestmark = pytest.mark.engine

T0 = datetime(2026, 11, 23, 20, 0, tzinfo=timezone.utc)


@pytest.fixture
def people(db_session: Session) -> dict[str, User]:
    """Three users (no password needed here) and a disabled one."""
    users = {name: User(name=name, role=role, password_hash="-", disabled=name == "gone")
             for name, role in (("ana", UserRole.ANNOTATOR), ("ben", UserRole.ANNOTATOR),
                                ("rita", UserRole.REVIEWER), ("gone", UserRole.ANNOTATOR))}
    db_session.add_all(users.values())
    db_session.flush()
    return users


@pytest.fixture
def two_games(db_session: Session) -> dict[str, list[int]]:
    """Game "a" with systems 1-4 (2 and 4 accepted, 3 and 4 with a label doubt), game "b" with 1-3."""
    out: dict[str, list[int]] = {}
    for match, n in (("a", 4), ("b", 3)):
        game = Game(league="l", season="s", match=match, source_path="/nowhere")
        db_session.add(game)
        db_session.flush()
        systems = [System(game_id=game.id, name=f"{i}.png", kind=SystemKind.SOCCERNET_V3,
                          label_doubts=1 if (match == "a" and i >= 3) else 0,
                          review_status=(ReviewStatus.ACCEPTED if (match == "a" and i % 2 == 0)
                                         else ReviewStatus.PENDING))
                   for i in range(1, n + 1)]
        db_session.add_all(systems)
        db_session.flush()
        out[match] = [s.id for s in systems]
    for sid in out["a"][2:]:
        db_session.add(Doubt(system_id=sid, kind="ball_off_consensus", accuses_label=True, message="test"))
    db_session.commit()
    return out


def _entries(session: Session, system_id: int) -> list[AuditEntry]:
    return list(session.scalars(sa.select(AuditEntry).where(AuditEntry.system_id == system_id)
                                .order_by(AuditEntry.id)))


def _queue_ids(session: Session, filters: SystemFilters) -> set[int]:
    return {s.id for s in queue.list_systems(session, filters, "name", limit=500).items}


def test_assign_one_system_records_who_when_and_an_audit_entry(db_session, people, two_games):
    sid = two_games["a"][0]
    done = assignment.assign(db_session, assignee="ana", system_ids=[sid], actor="rita", now=T0)
    assert (done.assignee, done.matched, done.changed, done.system_ids) == ("ana", 1, 1, [sid])
    db_session.expire_all()
    system = db_session.get(System, sid)
    assert (system.assignee_id, system.assigned_at, system.assigned_by) == (people["ana"].id, T0, "rita")
    [entry] = _entries(db_session, sid)
    assert (entry.action, entry.actor, entry.before, entry.after) == ("system.assign", "rita", {"assignee": None},
                                                                      {"assignee": "ana"})
    assert entry.game_id == system.game_id
    shown = assignment.assignments_of(db_session, [sid, two_games["b"][0]])
    assert shown[sid].assignee == "ana" and shown[sid].assigned_by == "rita"
    assert shown[two_games["b"][0]].assignee is None


def test_assign_a_game_then_again_changes_and_audits_only_what_changed(db_session, people, two_games):
    first = assignment.assign(db_session, assignee="ana", system_ids=[two_games["a"][1]], actor="rita", now=T0)
    assert first.changed == 1
    done = assignment.assign(db_session, assignee="ana", game_id=db_session.get(System, two_games["a"][0]).game_id,
                             actor="rita", now=T0 + timedelta(minutes=1))
    assert (done.matched, done.changed) == (4, 3)
    assert done.system_ids == sorted(set(two_games["a"]) - {two_games["a"][1]})
    assert len(_entries(db_session, two_games["a"][1])) == 1  # already hers: no second entry
    again = assignment.assign(db_session, assignee="ana", system_ids=two_games["a"], actor="rita")
    assert (again.matched, again.changed) == (4, 0)
    assert _queue_ids(db_session, SystemFilters(assignee="ana")) == set(two_games["a"])
    assert _queue_ids(db_session, SystemFilters(assignee="none")) == set(two_games["b"])
    assert _queue_ids(db_session, SystemFilters(assignee="ben")) == set()


def test_assign_a_queue_filters_result_across_pages(db_session, people, two_games):
    filters = SystemFilters(status=ReviewStatus.PENDING, doubt="any")
    done = assignment.assign(db_session, assignee="ben", filters=filters, actor="rita")
    assert done.system_ids == [two_games["a"][2]]  # pending and doubted: only a/3.png
    wider = assignment.assign(db_session, assignee="ana", filters=SystemFilters(status=ReviewStatus.PENDING,
                                                                                 assignee="none"), actor="rita")
    assert wider.system_ids == sorted([two_games["a"][0], *two_games["b"]])
    # the assignee filter combines with the others, as in the queue
    assert _queue_ids(db_session, SystemFilters(assignee="ben", status=ReviewStatus.PENDING)) == {two_games["a"][2]}
    page = queue.list_systems(db_session, SystemFilters(assignee="ana"), "-doubts", limit=2)
    assert page.total == 4 and len(page.items) == 2 and page.next_cursor is not None


def test_unassign_and_refusals_change_nothing(db_session, people, two_games):
    sid = two_games["b"][0]
    assignment.assign(db_session, assignee="ana", system_ids=[sid], actor="rita")
    done = assignment.assign(db_session, assignee=None, system_ids=[sid], actor="rita")
    assert done.changed == 1 and db_session.get(System, sid).assignee_id is None
    assert [e.after for e in _entries(db_session, sid)] == [{"assignee": "ana"}, {"assignee": None}]
    with pytest.raises(InvalidInputError) as err:
        assignment.assign(db_session, assignee="nobody", system_ids=[sid])
    assert err.value.field == "assignee"
    with pytest.raises(InvalidInputError) as err:
        assignment.assign(db_session, assignee="gone", system_ids=[sid])
    assert err.value.field == "assignee" and "disabled" in str(err.value)
    with pytest.raises(NotFoundError):
        assignment.assign(db_session, assignee="ana", system_ids=[sid, 10**9])
    with pytest.raises(InvalidInputError) as err:
        assignment.assign(db_session, assignee="ana", system_ids=[sid], game_id=1)
    assert err.value.field == "system_ids"
    db_session.expire_all()
    assert db_session.get(System, sid).assignee_id is None
    assert len(_entries(db_session, sid)) == 2


def test_an_assignment_is_reverted_like_an_edit(db_session, db_settings: Settings, people, two_games):
    sid = two_games["a"][0]
    assignment.assign(db_session, assignee="ana", system_ids=[sid], actor="rita")
    second = assignment.assign(db_session, assignee="ben", system_ids=[sid], actor="rita")
    assert second.changed == 1
    entry = _entries(db_session, sid)[-1]
    done = revert_entry(db_session, entry.id, settings=db_settings, actor="rita")
    assert (done.kind, done.ident) == ("system", sid)
    db_session.expire_all()
    assert db_session.get(System, sid).assignee_id == people["ana"].id
    last = _entries(db_session, sid)[-1]
    assert (last.action, last.reverts_id, last.after) == ("revert", entry.id, {"assignee": "ana"})
    # the first entry (None -> ana) cannot be reverted unforced: ana still has it, but the entry's after
    # is ana: that holds, so it reverts to nobody; after a reassignment to ben it conflicts
    assignment.assign(db_session, assignee="ben", system_ids=[sid], actor="rita")
    with pytest.raises(ConflictError):
        revert_entry(db_session, _entries(db_session, sid)[0].id, settings=db_settings, actor="rita")
    assert db_session.get(System, sid).assignee_id == people["ben"].id
    revert_entry(db_session, _entries(db_session, sid)[0].id, settings=db_settings, actor="rita", force=True)
    db_session.expire_all()
    assert db_session.get(System, sid).assignee_id is None


# ----- presence -------------------------------------------------------------------------------------
def test_a_claim_is_written_when_due_only_and_others_see_it(db_session, people, two_games):
    sid, ana, ben = two_games["a"][0], people["ana"].id, people["ben"].id
    first = presence.claim(db_session, sid, ana, T0)
    assert first.wrote and first.others == [] and first.mine.since == T0
    assert first.mine.expires_at == T0 + presence.TTL
    beat = presence.claim(db_session, sid, ana, T0 + timedelta(seconds=20))
    assert not beat.wrote and beat.mine.expires_at == T0 + presence.TTL
    seen = presence.claim(db_session, sid, ben, T0 + timedelta(seconds=30))
    assert [(p.name, p.since) for p in seen.others] == [("ana", T0)]
    refresh = presence.claim(db_session, sid, ana, T0 + presence.REFRESH_AFTER)
    assert refresh.wrote and refresh.mine.since == T0  # kept: she never left
    assert refresh.mine.expires_at == T0 + presence.REFRESH_AFTER + presence.TTL
    assert [p.name for p in refresh.others] == ["ben"]
    shown = presence.open_on(db_session, [sid, two_games["a"][1]], T0 + timedelta(seconds=70))
    assert [p.name for p in shown[sid]] == ["ana", "ben"] and two_games["a"][1] not in shown


def test_a_claim_expires_without_a_cleanup_job(db_session, people, two_games):
    sid, other, ana, ben = two_games["a"][0], two_games["b"][0], people["ana"].id, people["ben"].id
    presence.claim(db_session, sid, ana, T0)
    lapsed = T0 + presence.TTL
    assert presence.open_on(db_session, [sid], lapsed - timedelta(seconds=1))[sid][0].name == "ana"
    assert presence.open_on(db_session, [sid], lapsed) == {}  # gone for every reader at once
    rows = db_session.scalar(sa.select(sa.func.count()).select_from(SystemPresence))
    assert rows == 1  # still stored ...
    presence.claim(db_session, other, ben, lapsed + timedelta(seconds=5))  # ... until anyone's next claim
    assert db_session.scalars(sa.select(SystemPresence.user_id)).all() == [ben]
    back = presence.claim(db_session, sid, ana, lapsed + timedelta(seconds=10))
    assert back.wrote and back.mine.since == lapsed + timedelta(seconds=10)  # a new visit: since starts again
    assert presence.release(db_session, sid, ana) is True
    assert presence.open_on(db_session, [sid], lapsed + timedelta(seconds=11)) == {}
    assert presence.release(db_session, sid, ana) is False
    with pytest.raises(NotFoundError):
        presence.claim(db_session, 10**9, ana, T0)


def test_an_open_page_writes_twice_a_minute(db_session, db_engine, people, two_games):
    """Ten minutes of an open page heartbeating every HEARTBEAT: the statements that change the database
    are counted on the connection (the figure of the report: writes per minute per open page)."""
    sid, ana = two_games["a"][0], people["ana"].id
    writes: list[str] = []

    def count(conn, cursor, statement, params, context, executemany):
        if statement.lstrip().split(None, 1)[0].upper() in ("INSERT", "UPDATE", "DELETE"):
            writes.append(statement)

    connection = db_session.connection()
    sa.event.listen(connection, "before_cursor_execute", count)
    try:
        minutes = 10
        beats = int(timedelta(minutes=minutes) / presence.HEARTBEAT)
        wrote = [presence.claim(db_session, sid, ana, T0 + i * presence.HEARTBEAT).wrote for i in range(beats)]
    finally:
        sa.event.remove(connection, "before_cursor_execute", count)
    transactions = sum(wrote)
    # written at 0, 30, 60, ... 570 s: once per REFRESH_AFTER, never per heartbeat
    assert transactions == -(-timedelta(minutes=minutes).total_seconds() // presence.REFRESH_AFTER.total_seconds())
    assert transactions / minutes <= 2.0
    assert presence.TTL <= timedelta(seconds=60)  # a page gone without a word is not shown for long
    assert len(writes) == 2 * transactions  # each: one DELETE (lapsed claims and its own) and one INSERT
