"""``app.services.derivation.loading.load_systems`` (issue 29, item 2): systems with their views, one-to-one rows,
pairs and doubts in four queries, the same rows in the same order as the relationships' own lazy loads, and a
relation the session holds loaded left as it is. The synthetic SoccerNet-v3 dev set (40 systems)."""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Doubt, System
from app.services.calibration.players import frame_players
from app.services.derivation.loading import FRAME_ROWS, load_systems, load_view_players
from app.services.transfer.importing import import_soccernet_v3


def _shape(system: System) -> tuple:
    """Ids of what a system page and a recomputation read of ``system``, in the relationships' order."""
    tri = system.triangulation
    return (system.id, system.review is not None, system.game.id,
            [(f.id, f.position, *[getattr(f, r.key) is not None for r in FRAME_ROWS]) for f in system.frames],
            None if tri is None else (tri.system_id, [p.id for p in tri.pairs]),
            [d.id for d in system.doubts])


def _dev_set(shared_dir: Path, fresh_session_factory) -> Session:
    """A fresh database holding the synthetic SoccerNet-v3 dev set as imported."""
    session = fresh_session_factory("dev")
    settings = Settings(_env_file=None, database_url=str(session.get_bind().url), calibration_workers=1)
    import_soccernet_v3(session, shared_dir / "data/synthetic/soccernet-v3-dev", settings)
    return session


@contextmanager
def _statements(session: Session) -> Iterator[list[str]]:
    """The SQL statements the session's engine runs inside the block, in order."""
    statements: list[str] = []

    def count(_conn, _cursor, statement, *_rest) -> None:
        statements.append(statement)

    engine = session.get_bind()
    sa.event.listen(engine, "before_cursor_execute", count)
    try:
        yield statements
    finally:
        sa.event.remove(engine, "before_cursor_execute", count)


def test_load_systems_reads_what_the_lazy_loads_read_in_six_queries(shared_dir: Path, fresh_session_factory) -> None:
    session = _dev_set(shared_dir, fresh_session_factory)
    ids = session.scalars(sa.select(System.id).order_by(System.id)).all()
    assert len(ids) == 40
    session.expunge_all()
    lazy = {sid: _shape(session.get(System, sid)) for sid in ids}  # one lazy load per relation
    assert sum(len(s[5]) for s in lazy.values()) > 0 and all(s[4] is not None for s in lazy.values())
    session.expunge_all()

    with _statements(session) as statements:
        loaded = load_systems(session, [*reversed(ids), 999_999], (System.review, System.game), predictions=16)
        # one per list (predictions and person boxes too), any count
        assert [s.split()[0] for s in statements] == ["SELECT"] * 6
        statements.clear()
        assert {sid: _shape(s) for sid, s in loaded.items()} == lazy
        # the person boxes, every view's, as the lazy loads read them (plain rows, read back without a query)
        boxes = {f.id: frame_players(f) for s in loaded.values() for f in s.frames}
        assert sum(len(b) for b in boxes.values()) > 0
        assert statements == []  # everything read above was loaded
        session.expunge_all()
        assert boxes == {f.id: frame_players(f) for sid in ids for f in session.get(System, sid).frames}
        # the system page reads no person boxes: one query fewer
        session.expunge_all()
        statements.clear()
        load_systems(session, ids, (System.review, System.game), predictions=None, players=False)
        assert [s.split()[0] for s in statements if s != "BEGIN"] == ["SELECT"] * 4
    assert set(loaded) == set(ids)  # an id that names no system is left out

    # a list the session holds loaded is left as it is (a pending doubt stays in it)
    session.expunge_all()
    system = session.get(System, ids[0])
    pending = Doubt(kind="test", accuses_label=False, message="pending", evidence={})
    system.doubts.append(pending)
    with session.no_autoflush:
        again = load_systems(session, [ids[0]], predictions=16)[ids[0]]
    assert again is system and pending in again.doubts and len(again.doubts) == len(lazy[ids[0]][5]) + 1
    session.rollback()


def test_the_person_boxes_of_views_with_predictions_are_loaded_with_them(shared_dir: Path,
                                                                         fresh_session_factory) -> None:
    from app.db.models import Frame, Prediction

    session = _dev_set(shared_dir, fresh_session_factory)
    frame = session.scalars(sa.select(Frame).where(Frame.players.any()).order_by(Frame.id)).first()
    assert frame is not None
    sid, fid, boxes = frame.system_id, frame.id, sorted((p.x1, p.y1, p.x2, p.y2) for p in frame.players)
    session.add(Prediction(frame_id=fid, source="det", score=0.5, x1=10.0, y1=10.0, x2=20.0, y2=20.0))
    session.commit()
    session.expunge_all()

    with _statements(session) as statements:
        system = load_systems(session, [sid], predictions=16)[sid]
        # the five lists, and the person boxes
        assert [s.split()[0] for s in statements if s != "BEGIN"] == ["SELECT"] * 6
        statements.clear()
        (with_predictions,) = [f for f in system.frames if f.predictions]
        # an edit's recomputation reads them after changing objects: they must be there without a query
        assert sorted(box for _, _, box in frame_players(with_predictions)) == boxes and statements == []
        # asked again while the edit computes (the detector's check reads the boxes after the ball did): still none
        load_view_players(session, list(system.frames))
        assert statements == []
