"""Single-view systems: one SoccerNet-calibration frame (calibration datasets, many stadiums)."""
from __future__ import annotations

from app.db.models import SystemKind
from app.services.kinds.base import KindPolicy

#: No game rig (every frame may come from another stadium); broadcast priors hold (main cameras). Leaves v3d
#: as cameras (SoccerNet-calibration JSON, ``v3d export cameras``), never in the SoccerNet-v3D export (which
#: holds multi-view SoccerNet-v3 systems); exports of older versions that carried them still import.
SINGLE_VIEW = KindPolicy(
    kind=SystemKind.SINGLE_VIEW,
    import_formats=("sn-calibration", "soccernet-v3d"),
)
