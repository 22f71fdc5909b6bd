"""The enums the models store by value: system kinds, frame roles, calibration sources and statuses, ball
kinds, triangulation statuses, the evidence behind a 3D ball, job states, review statuses, user roles (the one home
of each; the API's ``Literal``s derive from them).
"""
from __future__ import annotations

import enum

from app.geometry.ball_evidence import TIER_DOUBTED, TIER_NONE, TIER_UNCONFIRMED, TIER_VOUCHED


# ----- enums ---------------------------------------------------------------------------------------
class SystemKind(str, enum.Enum):
    """How a multi-view system was formed."""

    SOCCERNET_V3 = "soccernet-v3"  # an action frame and its linked replays
    SINGLE_VIEW = "single-view"  # one frame of a calibration dataset, reviewed for its calibration
    ISSIA = "issia"  # one frame index of a sequence of synchronised static cameras (ISSIA-3D)


class FrameRole(str, enum.Enum):
    """The frame's part in its system."""

    ACTION = "action"
    REPLAY = "replay"
    CAMERA = "camera"  # the only view of a single-view system
    STATIC = "static"  # one static camera of a synchronised sequence (ISSIA-3D)


class CalibrationSource(str, enum.Enum):
    """Where a frame's camera comes from."""

    IMPORTED = "imported"  # read from a SoccerNet-v3D export, never recomputed on import
    COMPUTED = "computed"  # app.geometry.calibration.calibrate_frame on the current field lines
    EDITED = "edited"  # set by a reviewer


class CalibrationStatus(str, enum.Enum):
    """Outcome of calibration: a camera, or a refusal with its reason."""

    CALIBRATED = "calibrated"
    REFUSED = "refused"


class BallKind(str, enum.Enum):
    """A ball label is a box (SoccerNet-v3) or a point (ISSIA)."""

    BOX = "box"
    POINT = "point"


class TriangulationStatus(str, enum.Enum):
    """Outcome of a system's triangulation (method.md section 5)."""

    TRIANGULATED = "triangulated"  # at least one pair kept; ``ball3d`` is the mean of the kept points
    INSUFFICIENT_VIEWS = "insufficient_views"  # fewer than two admitted views with a ball label
    NO_PAIR_KEPT = "no_pair_kept"  # every pair dropped (tau, baseline, cheirality or degenerate)


class BallEvidence(str, enum.Enum):
    """What backs a system's stored 3D ball (``app.geometry.ball_evidence``, whose rule names the tiers), stored with
    the ball so that the queue filters by it without computing it; listed the best backed first (the queue's
    ``ball_evidence`` order)."""

    #: No label doubt, and evidence independent of the two rays that make a ball agrees with it.
    VOUCHED = TIER_VOUCHED
    #: It rests on the views' own agreement; nothing else checks it (typically two views).
    UNCONFIRMED = TIER_UNCONFIRMED
    #: A label doubt of the system names a view the ball uses.
    DOUBTED = TIER_DOUBTED
    #: The system has no 3D ball.
    NONE = TIER_NONE


class JobState(str, enum.Enum):
    """Where a background job is (``app.services.jobs.runner``)."""

    QUEUED = "queued"  # waiting for a runner
    RUNNING = "running"  # claimed by the runner named in ``Job.owner``, which beats ``heartbeat_at``
    DONE = "done"
    FAILED = "failed"  # ``Job.message`` says why


class ReviewStatus(str, enum.Enum):
    """A reviewer's decision on a system or a frame."""

    PENDING = "pending"
    ACCEPTED = "accepted"
    REJECTED = "rejected"
    NEEDS_FIX = "needs_fix"
    #: Systems only: the annotator a needs-fix was returned to says it is fixed; back with the reviewer who asked.
    FIXED = "fixed"


class UserRole(str, enum.Enum):
    """A user's role, least trusted first (``app.api.auth.ROLES``: a role may do what a lower one may)."""

    ANNOTATOR = "annotator"  # edits labels and field lines, takes per-view decisions
    REVIEWER = "reviewer"  # also takes system decisions and reverts audited writes
    ADMIN = "admin"  # also imports, exports and manages users
