"""What every system kind decides, with the defaults of broadcast footage (:class:`KindPolicy`)."""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from app.db.models import Frame, Game, System, SystemKind
from app.services.kinds.exports import EXPORTS, exports_of

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.datasets.records import CalibrationFields
    from app.geometry.camera import Camera
    from app.geometry.doubts import Doubt as DoubtFinding
    from app.geometry.triangulation import BallObservation

__all__ = ["EXPORTS", "KindPolicy", "game_stem", "image_stem", "split_of"]

#: Share of SoccerNet games in the train split (:func:`split_of`).
TRAIN_FRACTION = 0.8


def split_of(game_path: str) -> str:
    """"train" or "test" for a game, from a stable hash of ``league/season/match`` (about 80 / 20).

    >>> split_of("england_epl/2014-2015/2015-02-21 - 18-00 Chelsea 1 - 1 Burnley") in ("train", "test")
    True
    """
    h = int.from_bytes(hashlib.sha256(game_path.encode("utf-8")).digest()[:8], "big")
    return "train" if (h % 10_000) < TRAIN_FRACTION * 10_000 else "test"


def image_stem(game: Game, frame: Frame) -> str:
    """File stem of a view in the exports, unique across games: a slug of the match name, 8 hex digits
    of a hash of ``league/season/match`` and the frame's stem.

    >>> image_stem(Game(league="l", season="s", match="A 1 - 0 B"), Frame(name="12_3.png"))
    'A_1_-_0_B-80c8c009_12_3'
    """
    stem = Path(frame.name).stem
    return f"{game_stem(game)}_{re.sub(r'[^A-Za-z0-9-]+', '_', stem)}"


def game_stem(game: Game) -> str:
    """The game's part of a view's file stem: a slug of the match name (at most 40 characters) and 8 hex
    digits of a hash of ``league/season/match`` (two games of one name differ by the hash).

    >>> game_stem(Game(league="l", season="s", match="A 1 - 0 B"))
    'A_1_-_0_B-80c8c009'
    """
    slug = re.sub(r"[^A-Za-z0-9-]+", "_", game.match).strip("_")[:40] or "game"
    digest = hashlib.sha256(game.path.encode("utf-8")).hexdigest()[:8]
    return f"{slug}-{digest}"


@dataclass(frozen=True)
class KindPolicy:
    """The policy of one system kind. Subclasses (one module per kind) override what differs.

    Attributes:
        kind: the stored :class:`SystemKind`.
        import_formats: dataset formats whose readers produce systems of this kind (``v3d import ...``).
        exports: the names of :data:`EXPORTS` that write its systems (read from the exports' data,
            :data:`app.services.kinds.exports.SELECTIONS`).
        uses_rig: calibration may fix the camera centre at one of the game's positions (cameras fixed
            during a broadcast game; ``app.services.calibration.rigs.game_rig``).
        broadcast_priors: the broadcast camera-side priors hold (main camera on the y > 0 side), so the
            mirrored-labels flags are computed on recomputation.
        edit_locks_game: an edit of one system may change other systems of its game (a sequence's
            trajectory), so the edit locks the game row before the system's.
        computes_before_lock: an edit's recomputation reads nothing beyond its system and game
            (``app.services.derivation.recompute.stored_state_digest`` covers every row it reads), so the edit computes
            it before it takes the write lock and only compares and writes under it (``app.services.curation.editing``);
            False where it re-fits beyond the system (ISSIA's trajectory): computed under the lock.
        weighs_calibrations: the triangulation weighs each view by what its calibration from field lines is
            worth (``app.geometry.weighting.calibration_weight``: a view whose few lines leave its camera unsure
            neither makes a 3D ball with another weak one nor moves the ball two sure views make); False where
            the labels the triangulation uses are chosen otherwise (ISSIA's trajectory).
    """

    kind: SystemKind
    import_formats: tuple[str, ...]
    uses_rig: bool = False
    broadcast_priors: bool = True
    edit_locks_game: bool = False
    computes_before_lock: bool = True
    weighs_calibrations: bool = True

    @property
    def exports(self) -> frozenset[str]:
        """The names of :data:`EXPORTS` that write its systems: the exports' data says which kinds each writes."""
        return exports_of(self.kind)

    def split(self, system: System, frame: Frame) -> str:
        """"train" or "test" of one view in the exports and benchmarks: the split a release gave the image
        (``frame.split``, ``v3d import split``) where there is one, else (default) the game's hash split,
        :func:`split_of`."""
        return frame.split or split_of(system.game.path)

    def image_name(self, frame: Frame) -> str:
        """The name a file of per-image rows (precise boxes, ``v3d import precise-boxes``) gives one view of its
        game (default: the frame's name, e.g. ``12_1.png``)."""
        return frame.name

    def view_stem(self, game: Game, frame: Frame) -> str:
        """File stem of one view in the detector exports and the monocular benchmark, unique across
        games (default: :func:`image_stem`)."""
        return image_stem(game, frame)

    def consensus_observations(self, system: System, observations: list[BallObservation],
                               settings: Settings) -> list[BallObservation]:
        """The ball observations the system's triangulation uses (default: all those given, already
        restricted to admitted calibrations and included labels)."""
        return observations

    def judge_doubts(self, system: System, found: list[DoubtFinding],
                     cameras: dict[int, Camera] | None) -> list[DoubtFinding]:
        """The doubts stored for the system from those of the multi-view judgement ``found``
        (default: unchanged)."""
        return found

    def refine_calibration(self, session: Session, frame: Frame, fields: CalibrationFields,
                           settings: Settings) -> CalibrationFields:
        """A view's calibration from its edited field lines, refined with what the kind knows beyond the
        lines (read before the new calibration is stored: the stored one is the previous). Default: as it is."""
        return fields

    def calibration_refinement(self, frame: Frame) -> str | None:
        """What :meth:`refine_calibration` adds to ``frame``'s calibration beyond its lines, in a sentence, when it
        changes anything for this view (a dry run of an edit leaves it out and says so: it may take seconds);
        None when the lines' calibration is the whole of it. Default: None."""
        return None

    def refit_after_edit(self, session: Session, system: System, settings: Settings,
                         recalibrated: Frame | None = None) -> Sequence[System]:
        """Work beyond the system an edit of one of its views needs, in the edit's transaction; returns the
        systems recomputed by it (empty: the caller recomputes ``system`` itself). Default: nothing."""
        return []
