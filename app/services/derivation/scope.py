"""What an edit of a multi-view system reads and writes: the one declaration the loader, the concurrency check and
its tests derive from.

An edit of one view recomputes its whole system (``recompute.recompute_system``), so it reads and may write:

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

from app.db.models import Game, System
from app.db.scope import FRAME_ROWS, GAME_ROW, SYSTEM_LISTS, SYSTEM_ROWS, game_tables, system_tables

__all__ = ["FRAME_ROWS", "GAME_ROW", "SYSTEM_LISTS", "SYSTEM_ROWS", "changed", "game_changed", "game_tables",
           "system_tables"]


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
