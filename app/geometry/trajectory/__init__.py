"""Temporal 3D ball trajectory from synchronised static cameras (ISSIA-3D): the package's map.

The paper triangulates each frame on its own and names temporal tracking as future work. Here the
ball's physics is the check: between kicks and bounces the ball follows one of two models, fitted
to every label of every camera at once (reprojection residuals in pixels, robust loss):

* ``flight``: ``p(t) = p0 + v0 t + (0, 0, g t^2 / 2)``, ``g = 9.81 m/s^2`` (z points down);
* ``roll``: the ball on the grass, centre at ``z = -r`` (:data:`BALL_RADIUS_M`), horizontal
  ``p(t) = p0 + v0 t + a t^2 / 2`` (``a`` the rolling deceleration, fitted) until it stops
  (``t_stop = -(v0 . a) / |a|^2`` when it decelerates), then at rest.

A *piece* is a stretch of frames under one model with its own 6 parameters; breaks between pieces are kicks
and bounces. Pieces are found from the data, and a piece no ball could follow, or too short between two
others, is crossed by a Hermite curve instead (:mod:`~app.geometry.trajectory.segmentation` says how).

Each piece is fitted by iteratively reweighted linear least squares on the algebraic residual
``(r_1 - x r_3) . (p - C)``, ``(r_2 - y r_3) . (p - C)`` (``r_i`` rows of R, ``(x, y)`` the
undistorted normalised label), reweighted by the depth so that it equals the pixel error, with
Cauchy weights, then refined by a robust (Cauchy) least squares of the pixel residuals themselves;
both fits live in :mod:`app.geometry.motion` (the models, the batched linear fit the segmentation's
candidate cuts share, the Levenberg-Marquardt refinement with the analytic Jacobian). Residuals are
expressed on a 1920-px-wide image (:data:`app.geometry.pair_error.REFERENCE_WIDTH_PX`).

Outputs per frame (:class:`TrajectoryFit`): the trajectory's position, its source
(``triangulated``: the frame has its own triangulation from two or more kept labels; ``fitted``: one
kept label, position from the fit; ``interpolated``: no kept label, inside or between pieces), the
per-label residual and outlier flag (frame, camera) and the frame's own triangulation
(:func:`triangulate_frame`, the paper's pairwise method made robust to one wrong camera) from the
labels the trajectory keeps. :func:`refit_window` re-fits only the pieces an edit touches and answers
only the frames whose place on the trajectory can have changed, re-triangulating only those whose
kept labels changed (:func:`refit_local`, its fast path, reads only the pieces around the edit).

World: SoccerNet metres, origin at the centre spot, z down. Image: continuous pixels, origin at
the top-left corner. Pure: numpy only.

Modules, one idea each: :mod:`~app.geometry.trajectory.frames` (one frame's own triangulation),
:mod:`~app.geometry.trajectory.segmentation` (pieces found from the data), :mod:`~app.geometry.trajectory.fit`
(the whole sequence's fit and its per-frame assembly), :mod:`~app.geometry.trajectory.refit` (the re-fit after an
edit).
"""
from app.geometry.motion import BALL_RADIUS_M, GRAVITY_M_S2, KINDS
from app.geometry.trajectory.fit import SOURCES, TrajectoryFit, fit_trajectory
from app.geometry.trajectory.frames import FrameTriangulation, triangulate_frame
from app.geometry.trajectory.refit import REFIT_REACH, local_span, refit_local, refit_span, refit_window
from app.geometry.trajectory.segmentation import DEFAULT_BREAK_PX, DEFAULT_FLAG_PX, Piece

__all__ = ["GRAVITY_M_S2", "BALL_RADIUS_M", "KINDS", "SOURCES", "REFIT_REACH", "FrameTriangulation",
           "triangulate_frame",
           "Piece", "TrajectoryFit", "fit_trajectory", "local_span", "refit_local", "refit_span", "refit_window",
           "DEFAULT_BREAK_PX", "DEFAULT_FLAG_PX"]
