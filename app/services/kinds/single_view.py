"""Single-view systems: one SoccerNet-calibration frame (calibration datasets, many stadiums)."""
from __future__ import annotations

from app.db.models import SystemKind
from app.services.kinds.base import KindPolicy

#: No game rig (every frame may come from another stadium); broadcast priors hold (main cameras).
SINGLE_VIEW = KindPolicy(
    kind=SystemKind.SINGLE_VIEW,
    import_formats=("sn-calibration", "soccernet-v3d"),
    exports=frozenset({"soccernet-v3d", "yolo", "coco", "monocular"}),
)
