"""What an edit of a multi-view system reads and writes: the one declaration the loader, the concurrency check and
its tests derive from.

An edit of one view recomputes its whole system (``app.services.derivation.recompute.recompute_system``), so it
reads and may write:

* the system's row and its one-to-one rows (:data:`SYSTEM_ROWS`: triangulation, trajectory point, review);
* every view (``System.frames``) with the view's one-to-one rows (:data:`FRAME_ROWS`: field lines, calibration, ball
  label, review, reprojection, optimised box);
* the system's lists (:data:`SYSTEM_LISTS`: its doubts, its triangulation's pairs, its views' detector predictions);
* beyond the system, its game (:data:`GAME_ROW`): the game's camera prior and the calibrations of the game's other
  frames that make its camera rig (``app.services.calibration.rigs.rig_rows``).

Optimistic concurrency with a version column: the first set is covered by ``System.version``, the second by
``Game.version``. Every write of a row of the first set bumps its system's version in the same transaction
(:func:`changed`: every recomputation and every system decision call it), every write of the rig or of the prior
bumps the game's (:func:`game_changed`: ``apply_calibration`` and the import that learns a prior call it). A view's
decision (its review row's status and comment, which no recomputation reads) changes its frame's version alone
(``Frame.edit_version``, SQLAlchemy's version counter too), so a system decision's ETag covers what its reviewer
saw of the labels, lines, exclusions and calibrations while the reviewer's own view decisions on the same page
leave it valid, and an edit of that view written meanwhile fails the frame's compare. An edit reads the
versions with the rows, computes without holding a connection, then compares the versions under its write lock
(``app.services.curation.writing``): equal, nothing it read changed. ``tests/services/curation/test_edit_scope.py``
records the tables a recomputation reads and the transactions that write them, and fails when one is not covered.
"""
from __future__ import annotations

from typing import Any

from app.db.models import JAC_COLUMNS, Calibration, Frame, Game, System, Triangulation

#: The system's one-to-one rows an edit reads (joined to the system's row when it is loaded).
SYSTEM_ROWS: tuple[Any, ...] = (System.triangulation, System.trajectory_point, System.review)
#: Each view's one-to-one rows an edit reads (joined to the view's row when it is loaded).
FRAME_ROWS: tuple[Any, ...] = (Frame.calibration, Frame.ball_label, Frame.review, Frame.reprojection,
                               Frame.optimised_box, Frame.field_lines)
#: The system's lists an edit reads: its views, its doubts, its triangulation's pairs, its views' detector
#: predictions (each in id order but the views, in their place on the page) and its views' person boxes (the
#: detector's check and the players' placement of the mirror fix read them). An import or removal of predictions,
#: and an import that writes person boxes, bumps the version of each system it touches in its transaction.
SYSTEM_LISTS: tuple[Any, ...] = (System.frames, System.doubts, Triangulation.pairs, Frame.predictions, Frame.players)
#: The system's game: read by an edit for its camera prior and its version, which covers the game's rig.
GAME_ROW: Any = System.game


def system_tables() -> frozenset[str]:
    """The names of the tables whose rows of a system ``System.version`` covers: the system's own, its views', their
    one-to-one rows' and its lists' (module docstring)."""
    relations = (*SYSTEM_ROWS, *FRAME_ROWS, *SYSTEM_LISTS)
    return frozenset({System.__tablename__, *(r.property.mapper.local_table.name for r in relations)})


def game_tables() -> frozenset[str]:
    """The names of the tables ``Game.version`` covers for an edit: the game's row (its camera prior) and the rows its
    rig is read from (calibrations of its frames: ``rigs.rig_rows`` joins them to their frames and systems)."""
    return frozenset({Game.__tablename__, Frame.__tablename__, System.__tablename__,
                      Frame.calibration.property.mapper.local_table.name})


#: What ``Game.version`` covers column by column (the write unit checks it, ``app.db.unit``): the calibration columns
#: the game's rig is read from (``app.services.calibration.rigs.rig_rows``: status, camera, flags, JaC) and the game's
#: camera prior. A calibration's other columns (its admission under the last recomputation's settings, its reason,
#: residuals, time) and the game's others no edit of another system reads.
GAME_COLUMNS: dict[str, frozenset[str]] = {
    Calibration.__tablename__: frozenset({"frame_id", "status", "camera", "flags", *JAC_COLUMNS.values()}),
    Game.__tablename__: frozenset({"camera_prior"}),
}


#: The system kinds whose calibrations feed their game's camera rig (a kind's ``KindPolicy.uses_rig``): registered by
#: ``app.services.kinds``, which stands above this layer, when it is imported; the write unit checks a calibration's
#: change against ``Game.version`` only for these kinds (a calibration dataset's frames feed no rig).
RIG_KINDS: set[Any] = set()


#: Columns of the covered tables that no edit reads for its recomputation nor shows as what a version's ETag vouches
#: for: a write of them alone needs no version bump (the write unit's check, ``app.db.unit``, skips them). A system's
#: assignment (who works on it); the queue's copy of its decision (written from the decision, which is covered
#: itself); a view's split (which set an export files it in), its precise ball box (an evaluation's reference,
#: ``app.services.evaluation.boxes``) and what its dataset carries that v3d does not edit (``Frame.release``,
#: deferred: an edit never loads it), and where its image file is found (its pixels are the same wherever they are:
#: an import may find them in another folder or archive).
UNVERSIONED_COLUMNS: dict[str, frozenset[str]] = {
    System.__tablename__: frozenset({"assignee_id", "assigned_at", "assigned_by", "review_status"}),
    Frame.__tablename__: frozenset({"split", "precise_box", "release", "image_path", "image_root", "image_zip",
                                     "image_member", "image_type"}),
}


def changed(system: System) -> None:
    """Bump ``system``'s version in memory (flushed with the transaction's other writes): call it in every transaction
    that writes a row of the system's scope (module docstring). The flush's ``UPDATE`` of the system compares the
    version the system was loaded with (SQLAlchemy's version counter), so a write computed from rows another
    transaction has changed since fails with ``sqlalchemy.orm.exc.StaleDataError`` instead of overwriting them."""
    system.version = (system.version or 0) + 1


def game_changed(game: Game | None) -> None:
    """Bump ``game``'s version in memory (flushed with the transaction's other writes): call it in every transaction
    that changes a calibration feeding the game's rig or the game's camera prior. None (a system without a game
    loaded yet) does nothing."""
    if game is not None:
        game.version = (game.version or 0) + 1
