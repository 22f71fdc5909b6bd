"""Doubts: the label problems the geometry of one multi-view system can see, each with its evidence
and, where there is one, its fix.

A system's doubts are recomputed with every edit (``app.services.derivation.recompute``) and stored; this package
is pure (numpy / OpenCV, no database, no settings object). Kinds that accuse labels
(:data:`LABEL_KINDS`):

* ``mirrored_labels``: the view's field lines are labelled left for right (the verdict of
  ``app.geometry.mirror.mirror_evidence``, passed in through :class:`DoubtView`);
* ``ball_off_consensus``: the view's ball label disagrees with the ball the other views agree on;
* ``ball_missing``: a calibrated view without a ball label in which the ball of the other views
  reprojects inside the image;
* ``views_disagree``: the labelled views cannot all be right and the culprit cannot be told;
* ``near_duplicate_view``: two views from nearly the same viewpoint; names the one that adds nothing.
* ``ball_detected``: a view without a ball label in which a detector's box lies where the other views put the ball,
  at a ball's size there (:mod:`~.detections`, from stored predictions; its fix snaps the label to that box).

Information kinds (:data:`INFO_KINDS`) say why a view does not take part, without accusing a label, or give evidence
(``detection_off_label``: a detector agrees with the other views away from an outvoted label).

Each doubt carries a ``code`` (which reasoning found it, :data:`CODES`) and its numbers; the sentence a
person reads is composed above this module (``app.services.wording.doubt_words``).

Evidence is weighed by what each calibration is worth (:mod:`app.geometry.weighting`: the pixel sigma from
the stored calibration uncertainty): a view below admission whose calibration is sure still votes (half a
vote), an admitted view whose calibration is unsure votes half and is accused only beyond its own pixel sigma.
Agreement is
judged with each pair's conditioning: a pair whose rays meet only where no ball can be (under the grass,
far outside the stadium) does not agree, and a pair too poorly conditioned to triangulate (a near
duplicate) is judged by each label's distance to the other view's ray across the play volume
(:func:`epipolar_pair_error`). With one other labelled view the ball lies on that view's ray at an
unknown height: a view misses the ball only when that whole segment lies inside its image.

World frame: SoccerNet (metres, origin at the centre spot, z down). Pixels: continuous, origin at the
top-left corner of each view's own image.

Thresholds: :class:`DoubtSettings` (chosen with ``benchmarks/doubts.py`` and ``benchmarks/doubts_seeds.py``
on the sets that script names). The robust consensus lives in :mod:`app.geometry.consensus`.

Modules, one idea each: :mod:`~.contract` (the kinds, codes, a view as the judge sees it, a doubt, the
thresholds), :mod:`~.epipolar` (one label against another view's ray across the play volume), :mod:`~.judge`
(the rules that find doubts), :mod:`~.detections` (a detector's predictions checked against the other views); what a
calibration is worth is :mod:`app.geometry.weighting`'s, which the triangulation's service shares.
"""
from app.geometry.doubts.contract import (
    CODES,
    INFO_KINDS,
    LABEL_KIND_SEVERITY,
    LABEL_KINDS,
    SUGGESTION_ACTIONS,
    Doubt,
    DoubtSettings,
    DoubtView,
    label_severity,
)
from app.geometry.doubts.epipolar import epipolar_pair_error, ray_in_play_volume
from app.geometry.doubts.judge import consensus_box_sigma_px, consensus_fix, judge_system

__all__ = ["CODES", "INFO_KINDS", "LABEL_KINDS", "LABEL_KIND_SEVERITY", "SUGGESTION_ACTIONS", "Doubt",
           "DoubtSettings", "DoubtView", "label_severity", "epipolar_pair_error", "ray_in_play_volume",
           "consensus_box_sigma_px", "consensus_fix", "judge_system"]
