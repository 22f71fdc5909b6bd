"""SQLAlchemy 2 typed models of v3d.

Entity graph (``->`` is "has many", ``-`` is "has one")::

    Game -> System -> Frame - FieldLineAnnotation      (current + imported original, pixels)
                 |          - Calibration              (SoccerNet camera JSON, JaC@gamma, admitted)
                 |          - BallLabel                (box or point, current + imported original)
                 |          - BallReprojection         (fused 3D ball projected into the view)
                 |          - OptimisedBox             (paper Eq. min_diametre)
                 |          - ReviewDecision           (frame level)
                 - Triangulation -> TriangulationPair  (per pair e_ij, parallax, baseline, kept)
                 - ReviewDecision                      (system level)
                 -> ReviewHandoff, ReviewComment       (needs fix returned to a person; comments pinned on views)
                 -> Doubt                              (label problems the geometry sees, with fixes)
                 - TrajectoryPoint                     (ISSIA: the frame on the sequence's trajectory)

    User -> ApiToken                                   (people and their API tokens, hashed)
    System - User (assignee), SystemPresence           (work assignment; who has a system open, expiring)
    ServerSecret                                       (the session-signing key, shared by every worker)
    AuditEntry                                         (append-only log of accepted writes; ids, no FKs)
        - AuditState                                   (a large before / after state, stored once by digest)
    Job                                                (a background import, full recompute or export)
    Release -> ReleaseGame, ReleaseSystem              (a named, immutable snapshot of the accepted systems)
        - ReleaseDocument                              (their content as canonical JSON, stored once by digest)
    Frame -> Prediction                                (a ball detector's boxes, by source; never a label)
    Frame -> PlayerBox                                 (the players a dataset boxed, class and ID, as imported)

Units: pixels of the frame's own image (continuous coordinates, origin at the top-left corner),
world metres in SoccerNet's frame (z down), timestamps timezone-aware UTC. Boxes are
``[x1, y1, x2, y2]`` and points ``[x, y]`` JSON lists. Enums are stored by value.
The schema is created by the Alembic migrations (``migrations/``), never by ``create_all``.

One module per domain: :mod:`~.base` (the registry), :mod:`~.enums`, :mod:`~.labels` (what a dataset brings),
:mod:`~.derived` (what the recomputation derives), :mod:`~.review`, :mod:`~.accounts`, :mod:`~.operations`
(audit log, jobs), :mod:`~.releases`. Every model is importable from here; importing the package registers them all.
"""

from app.db.models.accounts import ApiToken, RateLimitCounter, ServerSecret, User
from app.db.models.base import JAC_COLUMNS, NAMING_CONVENTION, Base
from app.db.models.derived import BallReprojection, Calibration, Doubt, OptimisedBox, Triangulation, TriangulationPair
from app.db.models.enums import (
    BallEvidence,
    BallKind,
    CalibrationSource,
    CalibrationStatus,
    FrameRole,
    JobState,
    ReviewStatus,
    SystemKind,
    TriangulationStatus,
    UserRole,
)
from app.db.models.labels import BallLabel, FieldLineAnnotation, Frame, Game, PlayerBox, System, TrajectoryPoint
from app.db.models.operations import AuditEntry, AuditState, Job
from app.db.models.predictions import Prediction
from app.db.models.releases import Release, ReleaseDocument, ReleaseGame, ReleaseSystem
from app.db.models.review import (
    ReviewBatch,
    ReviewComment,
    ReviewDecision,
    ReviewHandoff,
    ReviewPass,
    SystemPresence,
)

__all__ = [
    "Base",
    "JAC_COLUMNS",
    "NAMING_CONVENTION",
    "BallEvidence",
    "BallKind",
    "CalibrationSource",
    "CalibrationStatus",
    "FrameRole",
    "JobState",
    "ReviewStatus",
    "SystemKind",
    "TriangulationStatus",
    "UserRole",
    "BallLabel",
    "FieldLineAnnotation",
    "Frame",
    "Game",
    "System",
    "TrajectoryPoint",
    "BallReprojection",
    "Calibration",
    "Doubt",
    "OptimisedBox",
    "Triangulation",
    "TriangulationPair",
    "Release",
    "ReleaseDocument",
    "ReleaseGame",
    "ReleaseSystem",
    "ReviewBatch",
    "ReviewComment",
    "ReviewDecision",
    "ReviewHandoff",
    "ReviewPass",
    "SystemPresence",
    "ApiToken",
    "RateLimitCounter",
    "ServerSecret",
    "User",
    "AuditEntry",
    "AuditState",
    "Job",
    "Prediction",
    "PlayerBox",
]
