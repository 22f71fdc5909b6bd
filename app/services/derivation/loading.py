"""Systems loaded with their views and derived rows in six queries, whatever the number of systems and views.

What a recomputation (``recompute.load_for_recompute``) and the system page (``app.services.curation.system_page``)
read of a system, as ``app.db.scope`` declares it: the system with its one-to-one rows joined to it,
its views (``System.frames``, in their order) with each view's one-to-one rows joined to it, its pairs
(``Triangulation.pairs``), doubts (``System.doubts``), its views' person boxes (``Frame.players``, for a recomputation)
and detector predictions (``Frame.predictions``, at
most ``V3D_MAX_PREDICTIONS_PER_FRAME`` a view, the best by score: ``app.db.models.predictions.ranked_predictions``,
so that a view flooded before the import's cap never reaches memory whole; none for the page, which draws none), in
id order. Each list is one query for all the systems asked;
its rows are handed to their parents as the loaded value of the relationship (``set_committed_value``), as SQLAlchemy's
``selectinload`` would, without its per-call loader machinery: a 4-view system loads in about two thirds of the CPU (an
edit's load, the page's load).

Like ``selectinload``, a relationship the session holds loaded already is left as it is (a system already in the
session gets only the relations it has not loaded; changed attributes are kept); the statements are built once.
"""
from __future__ import annotations

import functools
from typing import Any, Sequence, cast

import sqlalchemy as sa
from sqlalchemy.orm import InstanceState, Session, aliased, joinedload
from sqlalchemy.orm.attributes import set_committed_value

from app.db.models import Doubt, Frame, PlayerBox, Prediction, System, Triangulation, TriangulationPair
from app.db.models.predictions import ranked_predictions
from app.db.scope import FRAME_ROWS
from app.services.calibration.players import VIEW_PLAYERS, ViewPlayers

#: Systems loaded per round of queries (bounded IN lists and memory).
CHUNK = 500


@functools.cache
def _statements(system_rows: tuple[str, ...]) -> tuple[sa.Select, sa.Select, sa.Select, sa.Select, sa.Select]:
    """The five statements of :func:`load_systems` (systems, views, pairs, doubts, predictions), each taking the
    systems' ids as ``ids`` (an expanding parameter), the predictions' also ``per_frame`` (the most a view);
    ``system_rows``: the names of the system's one-to-one relationships joined to it (the triangulation always).
    Built once per ``system_rows``."""
    ids: sa.BindParameter[list[int]] = sa.bindparam("ids", expanding=True)
    ranked = ranked_predictions(Prediction.frame_id.in_(sa.select(Frame.id).where(Frame.system_id.in_(ids))))
    best = aliased(Prediction, ranked)
    return (
        sa.select(System).where(System.id.in_(ids)).options(
            *(joinedload(getattr(System, key)) for key in dict.fromkeys(("triangulation", *system_rows)))),
        sa.select(Frame).where(Frame.system_id.in_(ids)).order_by(Frame.system_id, Frame.position, Frame.id)
        .options(*(joinedload(r) for r in FRAME_ROWS)),
        sa.select(TriangulationPair).where(TriangulationPair.system_id.in_(ids)).order_by(TriangulationPair.id),
        sa.select(Doubt).where(Doubt.system_id.in_(ids)).order_by(Doubt.id),
        sa.select(best.frame_id, best).where(ranked.c.rank <= sa.bindparam("per_frame")).order_by(best.id),
    )


def load_systems(session: Session, ids: Sequence[int], system_rows: tuple[Any, ...] = (), *,
                 predictions: int | None, players: bool = True) -> dict[int, System]:
    """The systems ``ids`` that exist, by id, each with its views (and their one-to-one rows), triangulation and
    pairs, doubts, at most ``predictions`` predictions a view (the best by score; None: none loaded, the relationship
    left unloaded) and the one-to-one relationships ``system_rows`` (e.g. ``(System.review, System.game)``)
    loaded: six queries per :data:`CHUNK` systems (five without predictions, one fewer without ``players``; module
    docstring), the last for the views' person boxes (:func:`load_view_players`), which a recomputation reads (the
    page draws none)."""
    out: dict[int, System] = {}
    ids = list(dict.fromkeys(ids))
    systems_q, frames_q, pairs_q, doubts_q, predictions_q = _statements(tuple(r.key for r in system_rows))
    for start in range(0, len(ids), CHUNK):
        chunk = {"ids": ids[start:start + CHUNK]}
        systems = {s.id: s for s in session.scalars(systems_q, chunk).unique()}
        frames: dict[int, list[Frame]] = {i: [] for i in systems}
        for f in session.scalars(frames_q, chunk).unique():
            frames[f.system_id].append(f)
        pairs: dict[int, list[TriangulationPair]] = {i: [] for i in systems}
        for p in session.scalars(pairs_q, chunk):
            pairs[p.system_id].append(p)
        doubts: dict[int, list[Doubt]] = {i: [] for i in systems}
        for d in session.scalars(doubts_q, chunk):
            doubts[d.system_id].append(d)
        if predictions is not None:
            best: dict[int, list[Prediction]] = {f.id: [] for fs in frames.values() for f in fs}
            for fid, p in session.execute(predictions_q, {**chunk, "per_frame": predictions}):
                best[fid].append(p)
            for fs in frames.values():
                for f in fs:
                    _hand_over(f, "predictions", best[f.id])
        if players:  # the ball judged by evidence compares the players its views' cameras place, and the detector's
            load_view_players(session, [f for fs in frames.values() for f in fs])  # check reads the person boxes
        for sid, system in systems.items():
            _hand_over(system, "frames", frames[sid])
            _hand_over(system, "doubts", doubts[sid])
            tri: Triangulation | None = system.triangulation
            if tri is not None:
                _hand_over(tri, "pairs", pairs[sid])
        out.update(systems)
    return out


def load_view_predictions(session: Session, frames: Sequence[Frame], per_frame: int) -> None:
    """Hand each of ``frames`` whose predictions the session has not loaded (a view made by a script or a test's
    factory and flushed, never loaded by :func:`load_systems`) its best ``per_frame`` predictions, in one query, as
    :func:`load_systems` does; frames with theirs loaded are left as they are."""
    wanted = [f for f in frames if sa.inspect(f).persistent and "predictions" in sa.inspect(f).unloaded]
    if not wanted:
        return
    ranked = ranked_predictions(Prediction.frame_id.in_([f.id for f in wanted]))
    best = aliased(Prediction, ranked)
    found: dict[int, list[Prediction]] = {f.id: [] for f in wanted}
    for fid, p in session.execute(sa.select(best.frame_id, best).where(ranked.c.rank <= per_frame)
                                  .order_by(best.id)):
        found[fid].append(p)
    for f in wanted:
        _hand_over(f, "predictions", found[f.id])


@functools.cache
def _players_statement() -> sa.Select:
    """The person boxes of the frames ``ids`` (an expanding parameter), their columns as plain rows, in id order. A
    select of the table's columns, not of the mapped class's: the ORM's compilation of an entity statement is most of
    what executing one this small costs, and the rows are the same."""
    t = cast(sa.Table, PlayerBox.__table__).c
    return (sa.select(t.frame_id, t.cls, t.ident, t.x1, t.y1, t.x2, t.y2)
            .where(t.frame_id.in_(sa.bindparam("ids", expanding=True))).order_by(t.id))


def load_view_players(session: Session, frames: Sequence[Frame]) -> None:
    """Read the person boxes of each of ``frames`` whose boxes (``Frame.players``) the session has not loaded, in one
    query, as plain rows kept in the session (:data:`VIEW_PLAYERS`, read by
    ``app.services.calibration.players.frame_players``); frames with theirs loaded, or read so already, are left as
    they are (an edit reads them before it computes, and a read while it computes would hold a connection). Plain rows,
    not ORM objects: what reads them (the players check of the ball, the detector's check) reads their values only,
    and building a few dozen ORM objects was most of what the boxes cost an edit (``benchmarks/SCALE.md``)."""
    wanted = [f for f in frames if _players_unread(sa.inspect(f))]
    if not wanted:
        return
    found: dict[int, list[tuple[str, str | None, tuple[float, float, float, float]]]] = {f.id: [] for f in wanted}
    for fid, cls, ident, x1, y1, x2, y2 in session.execute(_players_statement(), {"ids": list(found)}):
        found[fid].append((cls, ident, (x1, y1, x2, y2)))
    for f in wanted:
        sa.inspect(f).info[VIEW_PLAYERS] = ViewPlayers(found[f.id])


def _players_unread(state: InstanceState) -> bool:
    """Whether a frame (its instance ``state``) is stored, with neither its person boxes loaded nor read as rows."""
    return state.persistent and "players" in state.unloaded and VIEW_PLAYERS not in state.info


def _hand_over(parent: Any, key: str, rows: list[Any]) -> None:
    """``rows`` as the loaded value of ``parent``'s list ``key``, unless the session holds it loaded already."""
    if key in sa.inspect(parent).unloaded:
        set_committed_value(parent, key, rows)
