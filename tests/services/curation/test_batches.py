"""Vouched systems accepted after a random sample (``app.services.curation.batches``): the plan's size, the systems a
batch takes, its accept when the sample was accepted by a person, its refusal (for good) by a rejected or changed
system, its wait for a sample not decided yet, its audit entries and its undo."""
from __future__ import annotations

import random
from typing import Any

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import ConflictError, InvalidInputError
from app.db.models import AuditEntry, ReviewDecision, ReviewStatus, System, SystemKind, User, UserRole
from app.db.models.enums import BallEvidence
from app.services.curation import batches, decisions, editing, passes
from app.services.curation.queue import SystemFilters
from app.services.evaluation.annotators import annotator_figures
from app.services.releases.content import create_release, read_systems, release_content
from tests.api.factories import Scene, ball_box, make_game, make_system

pytestmark = pytest.mark.engine


@pytest.mark.parametrize(("c", "p", "total", "n"), [
    (0.95, 0.05, 240, 59), (0.95, 0.05, 59, 59), (0.95, 0.05, 12, 12), (0.99, 0.01, 10_000, 459),
    (0.75, 0.5, 100, 2), (0.5, 0.5, 100, 1), (0.95, 0.05, 0, 0), (0.95, 5e-324, 240, 240), (0.95, 1e-12, 240, 240),
    (1 - 1e-16, 0.5, 240, 53)])
def test_the_sample_is_the_zero_acceptance_plans_size(c: float, p: float, total: int, n: int) -> None:
    assert batches.sample_size(c, p, total) == n
    if 0 < n < total:  # the plan's promise: n draws all right are as likely as 1 - c at most, n - 1 more likely
        assert (1 - p) ** n <= (1 - c) * (1 + 1e-9) < (1 - p) ** (n - 1)


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.1, 1.5, float("nan")])
def test_a_share_outside_zero_and_one_is_named(bad: float) -> None:
    with pytest.raises(InvalidInputError) as caught:
        batches.sample_size(bad, 0.05, 10)
    assert caught.value.field == "confidence"
    with pytest.raises(InvalidInputError) as caught:
        batches.sample_size(0.95, bad, 10)
    assert caught.value.field == "max_wrong_share"


@pytest.fixture
def five(db_session: Session, db_settings: Settings) -> list[Scene]:
    """Five three-view systems of one game: the first four vouched for, the last unconfirmed."""
    game = make_game(db_session)
    scenes = [make_system(db_session, db_settings, game, f"{i + 1}.png") for i in range(5)]
    for i, scene in enumerate(scenes):
        _system(db_session, scene.system_id).ball_evidence = (
            BallEvidence.VOUCHED if i < 4 else BallEvidence.UNCONFIRMED)
    db_session.commit()
    return scenes


def _system(session: Session, system_id: int) -> System:
    system = session.get(System, system_id)
    assert system is not None
    return system


def _batch(session: Session, seed: int = 3) -> batches.ReviewBatch:
    """A batch of the whole queue sampling 2 of the 4 vouched systems (75 % sure that at most half are wrong)."""
    return batches.create_batch(session, "rev", SystemFilters(), 0.75, 0.5, rng=random.Random(seed))


def _decide(session: Session, system_id: int, status: str, actor: str = "rev") -> None:
    if status == "needs_fix" and session.scalar(sa.select(User).where(User.name == "ben")) is None:
        session.add(User(name="ben", role=UserRole.ANNOTATOR, password_hash="not a hash: ben never logs in"))
        session.commit()
    decisions.decide_review(session, system_id=system_id, status=status, actor=actor,
                            return_to="ben" if status == "needs_fix" else None)


def test_a_batch_takes_the_pending_vouched_systems_and_draws_its_sample_at_random(
        db_session: Session, five: list[Scene]) -> None:
    ids = [s.system_id for s in five]
    _decide(db_session, ids[3], "rejected")  # decided: no longer pending
    batch = _batch(db_session)
    assert batch.system_ids == ids[:3] and batch.state == "open"
    assert batch.versions == [_system(db_session, i).version for i in ids[:3]]
    assert len(batch.sample_ids) == 2 and set(batch.sample_ids) <= set(ids[:3])
    assert batches.batch_plan(batch) == ("if none of these 2 is wrong, you can be 75 % sure that at most 50 % of the 3 "
                                         "are")
    samples = {tuple(_batch(db_session, seed).sample_ids) for seed in range(12)}
    assert len(samples) == 3  # every pair of the three is drawn by some seed
    game_only = batches.create_batch(db_session, "rev", SystemFilters(game_id=five[0].game_id + 1000), 0.95, 0.05)
    assert game_only.system_ids == [] and game_only.sample_ids == []
    with pytest.raises(InvalidInputError) as caught:
        batches.create_batch(db_session, "rev", SystemFilters(status=ReviewStatus.ACCEPTED), 0.95, 0.05)
    assert caught.value.field == "filter.status"


def test_a_batch_whose_sample_a_person_accepted_accepts_the_rest_each_with_its_audit_entry_and_undoes(
        db_session: Session, five: list[Scene]) -> None:
    batch = _batch(db_session)
    others = [i for i in batch.system_ids if i not in batch.sample_ids]
    with pytest.raises(ConflictError) as waiting:  # nothing decided yet: it waits, it is not refused
        batches.accept_batch(db_session, batch.id, "rev")
    assert all(f"system {i} of the sample is not decided yet" in str(waiting.value) for i in batch.sample_ids)
    assert batches.get_batch(db_session, batch.id).state == "open"
    for sid in batch.sample_ids:
        _decide(db_session, sid, "accepted", actor="ana")
    assert batches.stops(db_session, batch) == []
    versions = {i: _system(db_session, i).version for i in others}

    assert batches.accept_batch(db_session, batch.id, "rev") == len(others) == 2
    db_session.expire_all()
    for sid in others:
        system = db_session.get(System, sid)
        assert system is not None and system.review is not None
        assert system.review_status is ReviewStatus.ACCEPTED and system.review.batch_id == batch.id
        assert system.version == versions[sid] + 1
        entry = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.system_id == sid)
                                   .order_by(AuditEntry.id.desc())).first()
        assert entry is not None and entry.action == "system.review" and entry.actor == "rev"
        assert entry.after == {"review": {"status": "accepted", "comment": "", "batch_id": batch.id}}
        assert entry.summary == f"system accepted in batch {batch.id} after a sample"
    assert batches.get_batch(db_session, batch.id).state == "accepted"
    with pytest.raises(ConflictError, match="was accepted already"):
        batches.accept_batch(db_session, batch.id, "rev")

    # a person decides one of them again: the undo leaves it, and puts the other back to pending
    _decide(db_session, others[0], "rejected")
    undone = batches.undo_batch(db_session, batch.id, "rev")
    assert undone.undone == 1 and [s.system_id for s in undone.kept] == [others[0]]
    db_session.expire_all()
    assert _system(db_session, others[1]).review_status is ReviewStatus.PENDING
    assert _system(db_session, others[0]).review_status is ReviewStatus.REJECTED
    assert _system(db_session, others[1]).review.batch_id is None
    with pytest.raises(ConflictError, match="accepted nothing to undo"):
        batches.undo_batch(db_session, batch.id, "rev")


def test_a_rejected_sample_refuses_the_batch_for_good(db_session: Session, five: list[Scene]) -> None:
    batch = _batch(db_session)
    first, second = batch.sample_ids
    _decide(db_session, first, "rejected")
    _decide(db_session, second, "accepted")
    with pytest.raises(ConflictError) as refused:
        batches.accept_batch(db_session, batch.id, "rev")
    assert str(refused.value) == f"batch {batch.id} is refused: system {first} was rejected"
    assert batches.get_batch(db_session, batch.id).state == "refused"
    _decide(db_session, first, "accepted")  # accepting the rejected one afterwards changes nothing
    with pytest.raises(ConflictError) as again:
        batches.accept_batch(db_session, batch.id, "rev")
    assert str(again.value) == str(refused.value)
    assert all(_system(db_session, i).review_status is ReviewStatus.PENDING
               for i in batch.system_ids if i not in batch.sample_ids)


def test_a_sample_rejected_then_undone_still_stops_it(db_session: Session, five: list[Scene]) -> None:
    batch = _batch(db_session)
    first, second = batch.sample_ids
    _decide(db_session, first, "needs_fix")
    _decide(db_session, first, "accepted")
    _decide(db_session, second, "accepted")
    assert [(s.system_id, s.words, s.final) for s in batches.stops(db_session, batch)] == [
        (first, f"system {first} was returned for a fix", True)]


def test_a_change_of_an_unsampled_or_a_sampled_system_refuses_the_batch(
        db_session: Session, db_settings: Settings, five: list[Scene]) -> None:
    batch = _batch(db_session)
    scenes = {s.system_id: s for s in five}
    other = next(i for i in batch.system_ids if i not in batch.sample_ids)
    first, second = batch.sample_ids
    for sid in batch.sample_ids:
        _decide(db_session, sid, "accepted")
    # the ball of a view of an unsampled system, and of a sampled one after its accept, moved
    for sid in (other, second):
        scene = scenes[sid]
        editing.update_ball_label(db_session, scene.frame_ids[0], box=ball_box(scene.cameras[0], size_px=14.0),
                                  settings=db_settings, actor="ana")
    words = [s.words for s in batches.stops(db_session, batch)]
    assert f"system {other} changed since the batch was made" in words
    assert f"system {second} changed since the batch was made (ball.edit), beyond its decision" in words
    with pytest.raises(ConflictError, match=f"system {other} changed since the batch was made"):
        batches.accept_batch(db_session, batch.id, "rev")
    assert batches.get_batch(db_session, batch.id).state == "refused"


def test_overlapping_batches_reserve_nothing_and_the_later_accept_stops_the_earlier(
        db_session: Session, five: list[Scene]) -> None:
    one, two = _batch(db_session, seed=1), _batch(db_session, seed=1)
    assert one.system_ids == two.system_ids and one.id != two.id
    for sid in one.sample_ids:
        _decide(db_session, sid, "accepted")
    assert batches.accept_batch(db_session, two.id, "rev") == 2
    stopped = batches.stops(db_session, one)
    assert stopped and all(s.final for s in stopped)


def test_the_sample_pass_walks_the_sample_and_is_continued(db_session: Session, five: list[Scene]) -> None:
    batch = _batch(db_session)
    rp = batches.sample_pass(db_session, batch, "rev")
    assert rp.system_ids == batch.sample_ids and rp.sort == "sample" and rp.filters == {"batch_id": batch.id}
    assert batches.sample_pass(db_session, batch, "rev").id == rp.id
    assert batches.sample_pass(db_session, batch, "ana").id != rp.id
    _decide(db_session, batch.sample_ids[0], "accepted")
    place = passes.place(db_session, rp, batch.sample_ids[0])
    assert place.next_pending_id == batch.sample_ids[1] and place.total == 2


def test_a_new_release_says_how_each_system_was_accepted(db_session: Session, five: list[Scene]) -> None:
    batch = _batch(db_session)
    for sid in batch.sample_ids:
        _decide(db_session, sid, "accepted", actor="ana")
    batches.accept_batch(db_session, batch.id, "rev")
    release = create_release(db_session, "sampled", actor="rev")
    content = release_content(db_session, release)
    documents = read_systems(db_session, [d for _, _, d in content.systems.values()])
    accepted = {sid: documents[d].accepted for sid, (_, _, d) in content.systems.items()}
    assert sorted(accepted) == sorted(batch.system_ids)
    for sid, how in accepted.items():
        assert how is not None
        if sid in batch.sample_ids:
            assert how.as_json() == {"how": "person"}
        else:
            assert how.as_json() == {
                "how": "batch", "batch_id": batch.id, "confidence": 0.75, "max_wrong_share": 0.5, "sample": 2,
                "systems": 4,
                "plan": "if none of these 2 is wrong, you can be 75 % sure that at most 50 % of the 4 are"}


def test_a_batchs_acceptances_and_their_undo_are_no_persons_decisions(db_session: Session, five: list[Scene]) -> None:
    batch = _batch(db_session)
    for sid in batch.sample_ids:
        _decide(db_session, sid, "accepted", actor="ana")
    batches.accept_batch(db_session, batch.id, "rev")
    batches.undo_batch(db_session, batch.id, "rev")
    figures = {f.name: f for f in annotator_figures(db_session)}
    assert figures["ana"].decisions == figures["ana"].accepted == 2
    assert "rev" not in figures or figures["rev"].decisions == 0
    undo = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.action == "system.review")
                              .order_by(AuditEntry.id.desc())).first()
    assert undo is not None and undo.reverts_id is not None
    undone = db_session.get(AuditEntry, undo.reverts_id)
    assert undone is not None and undone.system_id == undo.system_id and undone.after["review"]["batch_id"] == batch.id


def _bare_vouched(session: Session, n: int) -> list[int]:
    """``n`` pending vouched systems of a new game, bare rows (the accept reads and writes no view)."""
    game = make_game(session, f"bare {n}")
    session.execute(sa.insert(System), [{"game_id": game.id, "name": f"{i}.png",
                                         "kind": SystemKind.SOCCERNET_V3, "ball_evidence": BallEvidence.VOUCHED}
                                        for i in range(n)])
    session.commit()
    return list(session.scalars(sa.select(System.id).where(System.game_id == game.id).order_by(System.id)))


def _statements_of_accept(session: Session, n: int, monkeypatch: pytest.MonkeyPatch
                          ) -> tuple[int, list[int], batches.ReviewBatch]:
    """A batch of ``n`` bare vouched systems whose sample a person accepted, accepted: the statements its write
    (``batches._accept``, after the checks) sent, the systems it accepted, the batch."""
    ids = _bare_vouched(session, n)
    batch = batches.create_batch(session, "rev", SystemFilters(game_id=session.get(System, ids[0]).game_id),
                                 0.75, 0.5, rng=random.Random(n))
    for sid in batch.sample_ids:
        _decide(session, sid, "accepted", actor="ana")
    sent: list[str] = []

    def count(_conn: Any, _cursor: Any, statement: str, *_args: Any) -> None:
        sent.append(statement)

    write = batches._accept

    def counted(*args: Any) -> None:
        engine = session.get_bind()
        sa.event.listen(engine, "before_cursor_execute", count)
        try:
            write(*args)
        finally:
            sa.event.remove(engine, "before_cursor_execute", count)

    monkeypatch.setattr(batches, "_accept", counted)
    monkeypatch.setattr(batches, "_CHUNK", 8)  # ids bound in chunks would show as more statements at this size
    batches.accept_batch(session, batch.id, "rev")
    monkeypatch.undo()
    return len(sent), [i for i in ids if i not in batch.sample_ids], batch


def test_a_batchs_accept_is_a_few_statements_whatever_its_size_with_an_entry_per_system(
        db_session: Session, monkeypatch: pytest.MonkeyPatch) -> None:
    small, _, _ = _statements_of_accept(db_session, 4, monkeypatch)
    large, accepted, batch = _statements_of_accept(db_session, 60, monkeypatch)
    # set-based: the same statements for 2 systems accepted as for 58 (a statement per system, or per chunk of
    # bound ids, would grow with the batch)
    assert large == small < 30
    db_session.expire_all()
    entries = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.system_id.in_(accepted),
                                                             AuditEntry.action == "system.review")
                                 .order_by(AuditEntry.id)).all()
    assert [e.system_id for e in entries] == accepted  # one each, in the systems' order
    versions = dict(db_session.execute(sa.select(System.id, System.version).where(System.id.in_(accepted))).all())
    for e in entries:
        assert e.before == {"review": {"status": "pending", "comment": ""}} and e.actor == "rev"
        assert e.after == {"review": {"status": "accepted", "comment": "", "batch_id": batch.id}}
        assert e.system_version == versions[e.system_id] == 2 and e.summary == (
            f"system accepted in batch {batch.id} after a sample")
    statuses = db_session.execute(sa.select(System.review_status, ReviewDecision.status, ReviewDecision.batch_id)
                                  .join(ReviewDecision, ReviewDecision.system_id == System.id)
                                  .where(System.id.in_(accepted))).all()
    assert len(statuses) == len(accepted)
    assert set(statuses) == {(ReviewStatus.ACCEPTED, ReviewStatus.ACCEPTED, batch.id)}
