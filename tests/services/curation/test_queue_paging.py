"""The review queue's pages (``app.services.curation.queue.list_systems``): by offset and by cursor, for
every sort and the filters, against the order computed here from the stored figures (NULLs last, ties by
id in the sort's direction, names in numeric order within a game)."""
from __future__ import annotations

import random
from datetime import datetime, timedelta, timezone
from typing import Any, Optional

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.api.queue_schemas import SystemSummaryOut
from app.core.errors import InvalidInputError
from app.db.models import (
    BallEvidence,
    Doubt,
    Game,
    ReviewDecision,
    ReviewStatus,
    System,
    SystemKind,
    Triangulation,
    TriangulationStatus,
)
from app.geometry.doubts import LABEL_KIND_SEVERITY, LABEL_KINDS, label_severity
from app.services.curation import queue
from app.services.curation.queue import SystemFilters

pytestmark = pytest.mark.engine

SORTS = ["-severity", "severity", "-doubts", "doubts", "-worst_error",
          "worst_error", "lowest_jac", "-lowest_jac", "name", "-name", "ball_evidence", "-ball_evidence"]
FILTERS = {
    "none": SystemFilters(),
    "pending": SystemFilters(status=ReviewStatus.PENDING),
    "error_min": SystemFilters(error_min=2.0),
    "doubt_any": SystemFilters(doubt="any"),
    "doubt_kind": SystemFilters(doubt="ball_off_consensus"),
    "vouched": SystemFilters(ball_evidence=BallEvidence.VOUCHED),
}


@pytest.fixture
def many(db_session: Session) -> list[System]:
    """61 systems in three games with ties and NULLs in every sort key (seed 5): doubts 0-2, errors
    from a set of 6 values or NULL, JaC from 5 values or NULL, a quarter reviewed."""
    rng = random.Random(5)
    games = [Game(league="england_epl", season="2014-2015", match=m, source_path="/nowhere")
             for m in ("b match", "a match", "c match")]
    db_session.add_all(games)
    db_session.flush()
    systems = []
    numbers = rng.sample(range(1, 200), 61)  # digits only: PostgreSQL's collation orders them as Python does
    for i in range(61):
        s = System(game_id=games[i % 3].id, name=f"{numbers[i]}.png", kind=SystemKind.SOCCERNET_V3,
                   label_doubts=rng.choice([0, 0, 1, 2]),
                   worst_error_px=rng.choice([None, 0.5, 1.25, 2.0, 3.5, 3.5, 9.0]),
                   lowest_jac=rng.choice([None, 0.6, 0.8, 0.8, 0.95]),
                   review_status=rng.choice([ReviewStatus.PENDING] * 3 + [ReviewStatus.ACCEPTED, ReviewStatus.FIXED]),
                   ball_evidence=rng.choice(list(BallEvidence)))
        systems.append(s)
    db_session.add_all(systems)
    db_session.flush()
    for s in systems[::4]:
        db_session.add(Doubt(system_id=s.id, kind="ball_off_consensus", accuses_label=True, message="test"))
    for s in systems[1::6]:  # severities 3 and 1, some beside a 2: the largest counts
        db_session.add(Doubt(system_id=s.id, kind="mirrored_labels", accuses_label=True, message="test"))
    for s in systems[2::5]:
        db_session.add(Doubt(system_id=s.id, kind="ball_detected", accuses_label=True, message="test"))
    db_session.flush()
    kinds: dict[int, list[str]] = {}
    for d in db_session.query(Doubt):
        kinds.setdefault(d.system_id, []).append(d.kind)
    for s in systems:  # the summary the recomputation stores with the doubts
        s.label_severity = label_severity(kinds.get(s.id, ()))
    db_session.flush()
    return systems


def _expected(db_session: Session, systems: list[System], sort: str, filters: SystemFilters) -> list[int]:
    """The queue's order computed in Python from the rows."""
    doubted = {d.system_id for d in db_session.query(Doubt).filter(Doubt.kind == "ball_off_consensus")}
    severity: dict[int, int] = {}
    for d in db_session.query(Doubt):
        severity[d.system_id] = max(severity.get(d.system_id, 0), LABEL_KIND_SEVERITY.get(d.kind, 0))
    rows = [s for s in systems if (filters.status is None or s.review_status == filters.status)
            and (filters.error_min is None or (s.worst_error_px is not None and s.worst_error_px >= filters.error_min))
            and (filters.doubt != "any" or s.label_doubts > 0)
            and (filters.doubt != "ball_off_consensus" or s.id in doubted)
            and (filters.ball_evidence is None or s.ball_evidence == filters.ball_evidence)]
    desc = sort.startswith("-")
    key = sort.lstrip("-")
    games = {g.id: g for g in db_session.query(Game)}

    def nulls_last(v: Optional[float], descending: bool) -> tuple[int, float]:
        return (1, 0.0) if v is None else (0, -v if descending else v)

    def sort_key(s: System) -> Any:
        sign = -1 if desc else 1
        if key == "severity":  # the work to do first in either direction
            return (s.review_status not in (ReviewStatus.PENDING, ReviewStatus.FIXED), sign * severity.get(s.id, 0),
                    nulls_last(s.worst_error_px, desc), sign * s.label_doubts, sign * s.id)
        if key == "doubts":
            return (sign * s.label_doubts, nulls_last(s.worst_error_px, True), sign * s.id)
        if key == "ball_evidence":  # vouched, unconfirmed, doubted, none; ties by the largest error
            rank = ["vouched", "unconfirmed", "doubted", "none"].index(s.ball_evidence.value)
            return (sign * rank, nulls_last(s.worst_error_px, True), sign * s.id)
        col = s.worst_error_px if key == "worst_error" else s.lowest_jac
        return (nulls_last(col, desc), sign * s.id)

    if key == "name":
        def name_key(s: System) -> Any:
            g = games[s.game_id]
            return (g.league, g.season, g.match, len(s.name), s.name, s.id)
        return [s.id for s in sorted(rows, key=name_key, reverse=desc)]
    return [s.id for s in sorted(rows, key=sort_key)]


@pytest.mark.parametrize("sort", SORTS)
@pytest.mark.parametrize("which", list(FILTERS))
def test_offset_and_cursor_pages_walk_the_same_order(db_session: Session, many: list[System], sort: str,
                                                     which: str) -> None:
    filters = FILTERS[which]
    expected = _expected(db_session, many, sort, filters)
    assert expected, "the fixture gives every filter some rows"
    whole = queue.list_systems(db_session, filters, sort, limit=500)
    assert [s.id for s in whole.items] == expected and whole.total == len(expected)
    assert whole.next_cursor is None and whole.prev_cursor is None
    # by offset, 7 a page
    by_offset = [queue.list_systems(db_session, filters, sort, limit=7, offset=o) for o in range(0, len(expected), 7)]
    assert [s.id for p in by_offset for s in p.items] == expected
    assert queue.list_systems(db_session, filters, sort, limit=7, offset=len(expected)).items == []
    # forwards by next_cursor, from the first page
    page, forwards, pages = queue.list_systems(db_session, filters, sort, limit=7), [], []
    while True:
        pages.append(page)
        forwards += [s.id for s in page.items]
        if page.next_cursor is None:
            break
        page = queue.list_systems(db_session, filters, sort, limit=7, after=page.next_cursor)
    assert forwards == expected
    assert pages[0].prev_cursor is None and all(p.prev_cursor for p in pages[1:])
    assert [[s.id for s in p.items] for p in pages] == [[s.id for s in p.items] for p in by_offset]
    # backwards by prev_cursor, from the last page
    page, backwards = pages[-1], []
    while True:
        backwards = [s.id for s in page.items] + backwards
        if page.prev_cursor is None:
            break
        page = queue.list_systems(db_session, filters, sort, limit=7, before=page.prev_cursor)
        assert page.next_cursor is not None
    assert backwards == expected
    # a cursor is a place in the order: after the 10th row, skipping 3 more
    tenth = queue.list_systems(db_session, filters, sort, limit=10)
    if tenth.next_cursor:
        assert [s.id for s in queue.list_systems(db_session, filters, sort, limit=5, offset=3,
                                                 after=tenth.next_cursor).items] == expected[13:18]


def test_a_cursor_made_under_other_filters_still_places_the_page(db_session: Session, many: list[System]) -> None:
    sort = "-worst_error"
    first = queue.list_systems(db_session, SystemFilters(), sort, limit=20)
    pending = _expected(db_session, many, sort, FILTERS["pending"])
    whole = _expected(db_session, many, sort, FILTERS["none"])
    after = [i for i in whole[20:] if i in pending]
    page = queue.list_systems(db_session, FILTERS["pending"], sort, limit=500, after=first.next_cursor)
    assert [s.id for s in page.items] == after


@pytest.mark.parametrize(("cursor", "message"), [
    ("not-a-cursor", "not a queue cursor"),
    (queue.encode_cursor("name", ("a", "b", "c", 1, "x", 3)), "sort='name'"),
    (queue.encode_cursor("-worst_error", (1.0,)), "not a queue cursor"),
    (queue.encode_cursor("-worst_error", (1.0, "7")), "system id"),
])
def test_bad_cursors_are_refused_naming_the_field(db_session: Session, many: list[System], cursor: str,
                                                  message: str) -> None:
    for field in ("after", "before"):
        with pytest.raises(InvalidInputError, match=message) as err:
            queue.list_systems(db_session, SystemFilters(), "-worst_error", **{field: cursor})
        assert err.value.field == field
    with pytest.raises(InvalidInputError, match="not both"):
        queue.list_systems(db_session, SystemFilters(), "-worst_error", after=cursor, before=cursor)


@pytest.mark.parametrize("sort", SORTS)
def test_neighbours_of_a_held_system_are_those_of_the_stored_one(db_session: Session, many: list[System],
                                                                    sort: str) -> None:
    """An edit's answer takes the sort keys of the system it holds instead of reading them (issue 29): every system's
    neighbours, in every sort and filter, are the ones the order computed here gives, read or held."""
    for which, filters in FILTERS.items():
        order = _expected(db_session, many, sort, filters)
        for s in many[::5]:
            read = queue.queue_neighbours(db_session, s.id, filters, sort)
            held = queue.queue_neighbours(db_session, s.id, filters, sort, held=s)
            assert held == read, (which, s.id)
            if s.id in order:
                i = order.index(s.id)
                assert read == (order[i - 1] if i > 0 else None, order[i + 1] if i + 1 < len(order) else None)


def test_a_held_system_spares_reading_its_sort_keys(db_session: Session, many: list[System]) -> None:
    """One statement (both neighbours) when the sort's keys are the system's own columns, or say their value for a
    system (the default order's work-to-do-first key, from its review status); the name sort, whose keys include its
    game's, reads them."""
    import sqlalchemy as sa

    seen: list[str] = []
    engine = db_session.get_bind().engine
    listener = lambda *a: seen.append(a[2])  # noqa: E731  # before_cursor_execute's statement
    sa.event.listen(engine, "before_cursor_execute", listener)
    try:
        for sort, statements in (("-doubts", 1), ("worst_error", 1), ("-severity", 1), ("severity", 1), ("name", 2)):
            seen.clear()
            queue.queue_neighbours(db_session, many[7].id, SystemFilters(), sort, held=many[7])
            assert len([s for s in seen if not s.startswith(("SAVEPOINT", "RELEASE"))]) == statements, sort
    finally:
        sa.event.remove(engine, "before_cursor_execute", listener)


def test_every_label_kind_has_a_severity() -> None:
    assert set(LABEL_KIND_SEVERITY) == set(LABEL_KINDS) and min(LABEL_KIND_SEVERITY.values()) >= 1


def _decided(db_session: Session, many: list[System]) -> None:
    """``many`` with what a queue row shows beside the stored figures: review decisions (decided, reset to pending
    with a reason, accepted by a batch), 3D balls (one triangulation without a ball), doubt counts and
    assignments; the session's objects expired, so that the ORM rows are read back as the plain rows are."""
    when = datetime(2026, 11, 29, 21, 30, 15, 123456, tzinfo=timezone.utc)
    for i, s in enumerate(many):
        if s.review_status != ReviewStatus.PENDING or i % 7 == 0:
            db_session.add(ReviewDecision(
                system_id=s.id, status=s.review_status, comment=f"comment {i}" if i % 2 else "",
                decided_at=None if s.review_status == ReviewStatus.PENDING else when + timedelta(minutes=i),
                reset_reason="a view was recalibrated" if s.review_status == ReviewStatus.PENDING else None,
                batch_id=3 if i % 5 == 0 and s.review_status == ReviewStatus.ACCEPTED else None))
        if i % 3:
            db_session.add(Triangulation(
                system_id=s.id, status=TriangulationStatus.TRIANGULATED if i % 9 else TriangulationStatus.NO_PAIR_KEPT,
                ball3d=[1.5 * i, -2.25, -0.11] if i % 9 else None, sigma_m=0.01 * i if i % 9 else None, tau_px=20.0,
                rule="pairs", min_baseline_m=1.0))
        s.doubt_counts = {"ball_off_consensus": 1} if i % 4 == 0 else {}
        s.ball_evidence_reasons = ["three views agree"] if i % 2 else []
        s.views_total, s.views_calibrated, s.views_admitted, s.views_labelled = 4, 3 + i % 2, 2 + i % 3, i % 5
        if i % 6 == 1:
            s.assigned_at, s.assigned_by = when, "lead"
    db_session.flush()
    db_session.expire_all()


@pytest.mark.parametrize("sort", ["-severity", "name", "-doubts", "lowest_jac"])
def test_the_apis_plain_rows_answer_what_the_orm_rows_answer(db_session: Session, many: list[System],
                                                             sort: str) -> None:
    """The queue's API reads its rows plain (``list_system_rows``, ``SystemSummaryOut.of_row``): every page, by offset
    and by cursor and under each filter, holds the systems, totals, counts and cursors of ``list_systems`` and each
    row answers what ``SystemSummaryOut.of`` makes of the ORM objects; a page's ``prev_cursor`` is there exactly when
    a row lies before it."""
    _decided(db_session, many)
    for filters in FILTERS.values():
        conds = queue._system_conditions(filters)
        pages = [{"offset": o} for o in range(0, 70, 7)]
        cursor = queue.list_systems(db_session, filters, sort, limit=7).next_cursor
        if cursor:
            pages += [{"after": cursor}, {"before": cursor}, {"after": cursor, "offset": 3}]
        for page in pages:
            orm = queue.list_systems(db_session, filters, sort, limit=7, **page)
            plain = queue.list_system_rows(db_session, filters, sort, limit=7, **page)
            assert [s.id for s in orm.items] == [r["id"] for r in plain.items]
            assert (orm.total, orm.counts, orm.next_cursor, orm.prev_cursor) == \
                (plain.total, plain.counts, plain.next_cursor, plain.prev_cursor)
            assert [SystemSummaryOut.of(s).model_dump(mode="json") for s in orm.items] == \
                [SystemSummaryOut.of_row(r).model_dump(mode="json") for r in plain.items]
            if orm.items:
                first = queue.sort_keys(sort)  # the row before the page's first, looked for in the order
                keys = db_session.execute(sa.select(*(k.expr for k in first)).select_from(System).join(
                    Game, Game.id == System.game_id).where(System.id == orm.items[0].id)).one()
                before = queue._walk(db_session, sort, conds, tuple(keys), "before", 1)
                assert (orm.prev_cursor is not None) == bool(before), page
    shown = [SystemSummaryOut.of_row(r) for r in queue.list_system_rows(db_session, SystemFilters(), sort,
                                                                          limit=100).items]
    assert {s.review.status for s in shown} >= {ReviewStatus.PENDING, ReviewStatus.ACCEPTED}
    assert any(s.review.reset_reason for s in shown) and any(s.review.batch_id for s in shown)
    assert any(s.ball3d for s in shown) and any(s.ball3d is None for s in shown)
