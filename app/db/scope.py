"""The rows a system's version and its game's version cover, declared on the models: read by the loader of an edit
(``app.services.derivation.scope``, whose docstring says what an edit reads and why) and by the write unit's check that
every transaction changing such a row bumps the version covering it (``app.db.unit``)."""
from __future__ import annotations

from typing import Any

from app.db.models import Frame, Game, System, Triangulation

#: The system's one-to-one rows an edit reads (joined to the system's row when it is loaded).
SYSTEM_ROWS: tuple[Any, ...] = (System.triangulation, System.trajectory_point, System.review)
#: Each view's one-to-one rows an edit reads (joined to the view's row when it is loaded).
FRAME_ROWS: tuple[Any, ...] = (Frame.calibration, Frame.ball_label, Frame.review, Frame.reprojection,
                               Frame.optimised_box, Frame.field_lines)
#: The system's lists an edit reads: its views, its doubts, its triangulation's pairs and its views' detector
#: predictions (each in id order but the views, in their place on the page). An import or removal of predictions
#: bumps the version of each system it touches in its transaction.
SYSTEM_LISTS: tuple[Any, ...] = (System.frames, System.doubts, Triangulation.pairs, Frame.predictions)
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


#: Columns of the covered tables that no edit reads for its recomputation nor shows as what a version's ETag vouches
#: for: a write of them alone needs no version bump. A system's assignment (who works on it); the queue's copy of its
#: decision (written from the decision, which is covered itself); a view's split (which set an export files it in), its
#: precise ball box (an evaluation's reference, ``app.services.evaluation.boxes``) and what its dataset carries that v3d
#: does not edit (``Frame.release``, deferred: an edit never loads it), and where its image file is found (its pixels
#: are the same wherever they are: an import may find them in another folder or archive).
UNVERSIONED_COLUMNS: dict[str, frozenset[str]] = {
    System.__tablename__: frozenset({"assignee_id", "assigned_at", "assigned_by", "review_status"}),
    Frame.__tablename__: frozenset({"split", "precise_box", "release", "image_path", "image_root", "image_zip",
                                     "image_member", "image_type"}),
}
