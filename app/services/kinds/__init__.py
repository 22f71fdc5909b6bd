"""One home per multi-view system kind: what differs between SoccerNet-v3 action frames with
their replays, single SoccerNet-calibration frames and ISSIA frame indices is decided by the kind's
module, and services ask it instead of branching on :class:`~app.db.models.SystemKind`.

* :mod:`.soccernet_v3`: an action frame and its replays of one broadcast game (game rigs, broadcast
  priors, every export).
* :mod:`.single_view`: one SoccerNet-calibration frame (no rig: frames come from many stadiums).
* :mod:`.issia`: one frame index of an ISSIA sequence seen by six static cameras (the sequence's
  trajectory judges labels; an edit re-fits the stretch of the trajectory it touches).

Use :func:`kind_of` (a system) or :func:`policy` (a kind) to get the :class:`~.base.KindPolicy`.
"""
from __future__ import annotations

from app.db import scope
from app.db.models import System, SystemKind
from app.services.kinds.base import EXPORTS, KindPolicy, game_stem, image_stem, split_of
from app.services.kinds.issia import ISSIA
from app.services.kinds.single_view import SINGLE_VIEW
from app.services.kinds.soccernet_v3 import SOCCERNET_V3

#: Every kind's policy, by kind.
POLICIES: dict[SystemKind, KindPolicy] = {p.kind: p for p in (SOCCERNET_V3, SINGLE_VIEW, ISSIA)}
# the write unit's check of Game.version reads which kinds have a rig (app.db.scope stands below the kinds)
scope.RIG_KINDS.update(p.kind for p in POLICIES.values() if p.uses_rig)


def policy(kind: SystemKind) -> KindPolicy:
    """The policy of ``kind``.

    Raises:
        KeyError: a kind no module owns (a new :class:`SystemKind` member without its module).
    """
    return POLICIES[kind]


def kind_of(system: System) -> KindPolicy:
    """The policy of ``system``'s kind (reads ``system.kind`` only)."""
    return POLICIES[system.kind]


def kinds_exported_by(export: str) -> list[SystemKind]:
    """The system kinds whose systems an export writes (``export``: one of :data:`EXPORTS`; the exports' data,
    :data:`app.services.kinds.exports.SELECTIONS`, says which).

    Raises:
        ValueError: an unknown export name.
    """
    if export not in EXPORTS:
        raise ValueError(f"unknown export {export!r}; one of {sorted(EXPORTS)}")
    return [k for k, p in POLICIES.items() if export in p.exports]


__all__ = ["EXPORTS", "KindPolicy", "POLICIES", "game_stem", "image_stem", "kind_of", "kinds_exported_by", "policy",
           "split_of"]
