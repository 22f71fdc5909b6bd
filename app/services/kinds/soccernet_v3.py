"""SoccerNet-v3 multi-view systems: an action frame and its replays of one broadcast game."""
from __future__ import annotations

from app.db.models import SystemKind
from app.services.kinds.base import KindPolicy

#: Cameras are fixed during a game (game rigs); broadcast priors; read from ``Labels-v3.json`` (SoccerNet-v3)
#: or ``Labels-v3D.json`` (a v3d export).
SOCCERNET_V3 = KindPolicy(
    kind=SystemKind.SOCCERNET_V3,
    import_formats=("soccernet-v3", "soccernet-v3d"),
    uses_rig=True,
)
