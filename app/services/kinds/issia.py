"""ISSIA multi-view systems: one frame index of a sequence seen by six static cameras around the pitch.

The sequence's physical trajectory (``app.services.issia.trajectory``) chooses the labels a system's
triangulation uses and judges them; an edit re-fits the stretch of the trajectory it touches, which may
recompute other systems of the sequence (``app.services.issia.sequences.refit_after_edit``), so an edit
locks the sequence's game row first.

The trajectory's work lives in the ISSIA services, which import the recomputation, which asks the kinds: so this
policy never imports them. They hand it their functions (:class:`IssiaHooks`) when their package is imported
(``app.services.issia``, which ``app.services`` imports first of all): a kind is data, its services register from
above, and the import graph has no circle (``tests/test_layers.py``).

Exports: ISSIA leaves as ISSIA-3D (``app.services.issia.export``) and in the detector exports and the
monocular benchmark, never in the SoccerNet-v3D export (which holds broadcast games). Its views are split as
in the paper, by camera (1-2 test, 3-6 train), and named ``<sequence slug>-<hash>_cam<k>_<frame index>``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Sequence

from app.datasets.issia import CAMERA_SET
from app.db.models import Frame, Game, System, SystemKind
from app.services.kinds.base import KindPolicy, game_stem

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.datasets.records import CalibrationFields
    from app.geometry.camera import Camera
    from app.geometry.doubts import Doubt as DoubtFinding
    from app.geometry.triangulation import BallObservation


#: Calibration flag of a camera the ISSIA import refined with the sequence's ball labels (bundle adjustment, ``v3d
#: import issia --from-lines``); a line edit of the view refines it so again (``app.services.issia.sequences``).
BALL_BUNDLE_FLAG = "ball_bundle"


@dataclass(frozen=True)
class IssiaHooks:
    """The ISSIA services' functions this policy delegates to, registered by ``app.services.issia``
    (:func:`register_hooks`): ``consensus_observations`` and ``merge_doubts`` of ``app.services.issia.trajectory``,
    ``refined_with_ball`` and ``refit_after_edit`` of ``app.services.issia.sequences`` (their own signatures)."""

    consensus_observations: Callable[..., Any]
    merge_doubts: Callable[..., Any]
    refined_with_ball: Callable[..., Any]
    refit_after_edit: Callable[..., Any]


_HOOKS: list[IssiaHooks] = []  # the registered hooks, the last one (an empty list: none yet)


def register_hooks(hooks: IssiaHooks) -> None:
    """Give the ISSIA policy its services' functions (called once, by ``app.services.issia`` on import)."""
    _HOOKS.append(hooks)


def _hooks() -> IssiaHooks:
    """The registered :class:`IssiaHooks`.

    Raises:
        RuntimeError: none is registered (``app.services.issia`` was never imported: ``app.services`` imports it).
    """
    if not _HOOKS:
        raise RuntimeError("the ISSIA kind's hooks are not registered: import app.services.issia")
    return _HOOKS[-1]


@dataclass(frozen=True)
class IssiaPolicy(KindPolicy):
    """Static cameras on every side of the pitch: no broadcast priors, no game rig; the trajectory."""

    def split(self, system: System, frame: Frame) -> str:
        """The split a release gave the view (``frame.split``) where there is one, else the paper's split by
        camera: cameras 1-2 "test", 3-6 "train" (:data:`app.datasets.issia.CAMERA_SET`; a view of another
        camera is "train")."""
        return frame.split or CAMERA_SET.get(frame.name.removeprefix("cam"), "train")

    def image_name(self, frame: Frame) -> str:
        """``cam<k>_<frame index, 6 digits>``: one name per view of the sequence (the end of :meth:`view_stem`; a
        camera's frames share its name ``cam<k>``).

        Raises:
            ValueError: the view's system has no frame index.
        """
        index = frame.system.frame_index
        if index is None:
            raise ValueError(f"ISSIA view {frame.name!r} of system {frame.system.name!r} has no frame index")
        return f"{frame.name}_{index:06d}"

    def view_stem(self, game: Game, frame: Frame) -> str:
        """``<sequence slug>-<hash>_cam<k>_<frame index, 6 digits>``: one file per view (camera and frame
        index), unique across sequences (:func:`~app.services.kinds.base.game_stem`).

        Raises:
            ValueError: the view's system has no frame index.
        """
        return f"{game_stem(game)}_{self.image_name(frame)}"

    def consensus_observations(self, system: System, observations: list[BallObservation],
                               settings: Settings) -> list[BallObservation]:
        """The labels the sequence's trajectory keeps that agree (``app.services.issia.trajectory``)."""
        return _hooks().consensus_observations(system, observations, settings)

    def judge_doubts(self, system: System, found: list[DoubtFinding],
                     cameras: dict[int, Camera] | None) -> list[DoubtFinding]:
        """The multi-view doubts merged with the trajectory's judgement of the labels."""
        return _hooks().merge_doubts(system, found, cameras)

    def refine_calibration(self, session: Session, frame: Frame, fields: CalibrationFields,
                           settings: Settings) -> CalibrationFields:
        """A camera the import refined with the ball's labels is refined with them again after a line edit
        (``app.services.issia.sequences.refined_with_ball``)."""
        return _hooks().refined_with_ball(session, frame, fields, settings)

    def calibration_refinement(self, frame: Frame) -> str | None:
        """A camera the import refined with the ball's labels (flag ``BALL_BUNDLE_FLAG``) is refined again on commit,
        from the sequence's ball labels (about a second): the lines alone give another camera."""
        cal = frame.calibration
        if cal is None or BALL_BUNDLE_FLAG not in (cal.flags or ()):
            return None
        return ("on release this camera is also refined with the sequence's ball labels, as the import refined it: "
                "the preview shows the fit of the lines alone")

    def refit_after_edit(self, session: Session, system: System, settings: Settings,
                         recalibrated: Frame | None = None) -> Sequence[System]:
        """Re-fit the trajectory's stretch the edit touches and recompute the systems whose place on it
        changed (``app.services.issia.sequences.refit_after_edit``)."""
        return _hooks().refit_after_edit(session, system, settings, recalibrated=recalibrated)


ISSIA = IssiaPolicy(
    kind=SystemKind.ISSIA,
    import_formats=("issia",),
    broadcast_priors=False,
    edit_locks_game=True,
    computes_before_lock=False,
    weighs_calibrations=False,
)
