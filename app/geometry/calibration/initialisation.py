"""Starting cameras for the non-linear refinement.

Three families:

* **Homography from lines** (:func:`ground_homographies`): every annotated point ``p`` of a
  straight ground element with world line ``l`` (homogeneous, ground plane) gives one linear
  equation ``l^T G p = 0`` on the image-to-ground homography ``G`` (the point-on-line form of the
  line DLT, Hartley and Zisserman section 4.1 with line correspondences, with their data
  normalisation, section 4.4.4). Four or more lines with at least two along each pitch direction
  fix ``G``. :func:`camera_from_homography` then recovers focal length, rotation and centre with the
  principal point fixed and square pixels (Zhang 2000, closed form from the two orthonormality
  constraints on ``K^-1 H``).
* **Look-at priors** (:func:`app.geometry.camera.look_at_rotation`): a camera at a plausible broadcast position looking
  at the labelled part of the pitch, for frames whose lines do not fix a homography.
* **Known centre** (:func:`fixed_centre_rotations`): with the camera centre known (a game's rig),
  the rotation that brings the image rays of the labels' anchors (:func:`anchor_correspondences`)
  onto their world directions (Wahba's problem, :func:`wahba_rotation`), per focal hypothesis.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from app.geometry.calibration.observations import Observations
from app.geometry.calibration.residuals import JIT
from app.geometry.pitch import GOAL_CLASSES

_WORLD_SCALE_M = 50.0


def fit_conic(points: np.ndarray) -> np.ndarray | None:
    """Algebraic least-squares conic through image points (Hartley and Zisserman, section 2.2.3).

    Args:
        points: (N, 2) points, N >= 5, in any consistent unit.

    Returns:
        (3, 3) symmetric conic ``C`` with ``p^T C p = 0`` on the curve, or ``None`` when the points
        do not determine an ellipse (fewer than 5, degenerate, or a hyperbola/parabola fits best).

    >>> t = np.linspace(0.0, 2.0, 9); C = fit_conic(np.stack([3 + 2 * np.cos(t), 1 + np.sin(t)], 1))
    >>> p = np.array([3.0, 2.0, 1.0]); bool(abs(p @ C @ p) < 1e-9)
    True
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) < 5:
        return None
    mu = pts.mean(axis=0)
    sc = float(np.sqrt(np.mean(np.sum((pts - mu) ** 2, axis=1)))) or 1.0
    q = (pts - mu) / sc
    x, y = q[:, 0], q[:, 1]
    D = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=1)
    _, s, vt = np.linalg.svd(D, full_matrices=False)
    if s[-2] < 1e-6 * s[0]:
        return None
    a, b, c, d, e, f = vt[-1]
    Cn = np.array([[a, b / 2, d / 2], [b / 2, c, e / 2], [d / 2, e / 2, f]])
    if b * b - 4 * a * c >= 0:
        return None
    T = np.array([[1 / sc, 0, -mu[0] / sc], [0, 1 / sc, -mu[1] / sc], [0, 0, 1]])
    C = T.T @ Cn @ T
    return C / np.linalg.norm(C)


def _fit_image_line(pts: np.ndarray) -> np.ndarray | None:
    """Total-least-squares homogeneous line (3,) through (N, 2) points; ``None`` if they coincide."""
    mu = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - mu, full_matrices=False)
    if len(pts) < 2 or s[0] < 1e-6:
        return None
    n = vt[-1]
    return np.array([n[0], n[1], -n @ mu])


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of two 3-vectors with the same products and differences (equal to the bit), without its
    broadcasting machinery: the ground equations take a few per labelled line, in every calibration."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _line_conic_points(line: np.ndarray, conic: np.ndarray) -> np.ndarray | None:
    """The two intersections (2, 3) of a homogeneous line with a conic, or ``None`` if they are not real."""
    n = line[:2]
    nn = float(n @ n)
    if nn < 1e-300:
        return None
    p0 = -line[2] * n / nn  # point of the line nearest the origin
    d = np.array([-n[1], n[0]]) / np.sqrt(nn)
    P0 = np.array([p0[0], p0[1], 1.0])
    D = np.array([d[0], d[1], 0.0])
    a = D @ conic @ D
    b = 2.0 * (P0 @ conic @ D)
    c = P0 @ conic @ P0
    disc = b * b - 4 * a * c
    if abs(a) < 1e-300 or disc < 0:
        return None
    r = np.sqrt(disc)
    ts = np.array([(-b - r) / (2 * a), (-b + r) / (2 * a)])
    return P0[None, :] + ts[:, None] * D[None, :]


def _point_rows(world: np.ndarray, image: np.ndarray) -> np.ndarray:
    """DLT rows of ``world x (G image) = 0`` for one point pair (homogeneous (3,) each); rank 2."""
    w = world / np.linalg.norm(world)
    q = image / np.linalg.norm(image)
    return np.kron(_skew(w), q[None, :]).reshape(3, 9)


@dataclass(frozen=True)
class _Equations:
    lines: np.ndarray  # (n, 9) rows from points on lines
    n_line_eq: int
    points: list[np.ndarray]  # unambiguous point pairs, each (2, 9)
    pairs: list[tuple[np.ndarray, np.ndarray]]  # ambiguous pairs: rows for both assignments, each (4, 9)


def _ground_equations(obs: Observations, T: np.ndarray, S: np.ndarray, with_pairs: bool) -> _Equations:
    is_ground = np.array([c not in GOAL_CLASSES for c in obs.seg_classes], dtype=bool)
    rows: list[np.ndarray] = []
    n_eq = 0
    image_lines: list[tuple[np.ndarray, np.ndarray]] = []
    for i in np.flatnonzero(is_ground):
        pts = obs.seg_points[obs.seg_index == i]
        a = S @ np.array([obs.seg_a[i][0], obs.seg_a[i][1], 1.0])
        b = S @ np.array([obs.seg_b[i][0], obs.seg_b[i][1], 1.0])
        lw = _cross3(a, b)
        lw /= np.linalg.norm(lw)
        pn = np.hstack([pts, np.ones((len(pts), 1))]) @ T.T
        rows.append((lw[None, :, None] * pn[:, None, :]).reshape(len(pts), 9) / np.sqrt(len(pts)))
        n_distinct = 1 if np.ptp(pts, axis=0).max() < 1.0 else 2
        n_eq += n_distinct
        if n_distinct == 2:
            li = _fit_image_line(pn[:, :2])
            if li is not None:
                image_lines.append((lw, li / np.linalg.norm(li)))
    points: list[np.ndarray] = []
    pairs: list[tuple[np.ndarray, np.ndarray]] = []
    # Known image points: intersections of perpendicular labelled lines.
    known: list[tuple[np.ndarray, np.ndarray]] = []
    for u in range(len(image_lines) if with_pairs else 0):
        for v in range(u + 1, len(image_lines)):
            pw = _cross3(image_lines[u][0], image_lines[v][0])
            pi = _cross3(image_lines[u][1], image_lines[v][1])
            if abs(pw[2]) > 1e-9 * np.linalg.norm(pw):
                known.append((pw / pw[2], pi))
    for j in range(len(obs.circle_classes)):
        pts = obs.circle_points[obs.circle_index == j]
        conic = fit_conic((np.hstack([pts, np.ones((len(pts), 1))]) @ T.T)[:, :2]) if len(pts) >= 5 else None
        if conic is None:
            continue
        cx, cy = obs.circle_centre[j] / _WORLD_SCALE_M
        rr = obs.circle_radius[j] / _WORLD_SCALE_M
        Q = np.array([[1, 0, -cx], [0, 1, -cy], [-cx, -cy, cx * cx + cy * cy - rr * rr]])
        for lw, li in image_lines:
            # Pole of the line: unambiguous (pole-polar duality is projective).
            try:
                points.append(_point_rows(np.linalg.solve(Q, lw), np.linalg.solve(conic, li)))
            except np.linalg.LinAlgError:
                pass
            # The line meets the circle: its two crossings, assignment unknown.
            if not with_pairs:
                continue
            ww = _line_conic_points(lw, Q)
            ii = _line_conic_points(li, conic)
            if ww is not None and ii is not None:
                pairs.append(_pair_rows(ww, ii))
        for pw, pi in known[:2] if with_pairs else ():
            # Tangency points seen from a known point: on its polar, assignment unknown.
            ww = _line_conic_points(Q @ pw, Q)
            ii = _line_conic_points(conic @ pi, conic)
            if ww is not None and ii is not None:
                pairs.append(_pair_rows(ww, ii))
    lines = np.concatenate(rows) if rows else np.zeros((0, 9))
    return _Equations(lines=lines, n_line_eq=n_eq, points=points, pairs=pairs)


def _pair_rows(ww: np.ndarray, ii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    same = np.vstack([_point_rows(ww[0], ii[0]), _point_rows(ww[1], ii[1])])
    swapped = np.vstack([_point_rows(ww[0], ii[1]), _point_rows(ww[1], ii[0])])
    return same, swapped


def _solve_dlt(A: np.ndarray, T: np.ndarray, S: np.ndarray) -> np.ndarray | None:
    if len(A) < 8:
        return None
    # Only the right singular vectors are needed: without U (n x n) when n >= 9 rows, where all nine
    # are computed anyway; with exactly 8 rows the ninth (the null vector) needs the full decomposition.
    _, s, vt = np.linalg.svd(A, full_matrices=len(A) < A.shape[1])
    if s[7] < 1e-9 * s[0] if len(s) > 7 else True:
        return None
    G = vt[-1].reshape(3, 3)
    # Normalised: X_n = G p_n with p_n = T p and X_n = S X, so X = S^-1 G T p.
    try:
        H = np.linalg.inv(np.linalg.inv(S) @ G @ T)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(H)):
        return None
    return H / np.linalg.norm(H)


def ground_homographies(obs: Observations, principal_point: np.ndarray, scale_px: float,
                        max_ambiguous: int = 3) -> list[tuple[str, np.ndarray]]:
    """Candidate ground-to-image homographies from the labelled ground lines and circles.

    Equations (all linear in the image-to-ground homography ``G``, with Hartley's normalisation,
    Hartley and Zisserman, section 4.4.4):

    * each annotated point ``p`` on a ground element of world line ``l``: ``l^T G p = 0``;
    * for every labelled circle with 5 points or more, fitted by an image conic ``C``
      (:func:`fit_conic`): the pole of each labelled line, ``C^-1 l_image`` <-> ``Q^-1 l_world``
      (pole-polar duality is projective, Hartley and Zisserman, section 2.8.1);
    * two-fold ambiguous point pairs: where a labelled line crosses the circle (middle line and
      central circle, 18-yard line and penalty arc), and the tangency points seen from a known
      corner (the intersection of two labelled lines) on its polar. Each assignment is tried, for
      at most ``max_ambiguous`` such pairs.

    Args:
        obs: the frame's observations (goal elements are ignored: they are off the ground).
        principal_point: (2,) px, used to centre the image points. scale_px: px, to scale them.
        max_ambiguous: most ambiguous pairs combined (2^n systems are solved).

    Returns:
        ``[(name, H)]``: (3, 3) homographies mapping ground (x, y, 1) metres to pixels, possibly
        empty when the labels do not fix one.
    """
    T = np.array([[1 / scale_px, 0, -principal_point[0] / scale_px],
                  [0, 1 / scale_px, -principal_point[1] / scale_px], [0, 0, 1]])
    S = np.diag([1 / _WORLD_SCALE_M, 1 / _WORLD_SCALE_M, 1.0])
    nx, ny = obs.ground_line_directions()
    lines_suffice = nx >= 2 and ny >= 2
    # The ambiguous conic pairs are only needed when the lines alone do not fix the homography.
    eq = _ground_equations(obs, T, S, with_pairs=not lines_suffice)
    out: list[tuple[str, np.ndarray]] = []
    if lines_suffice:
        H = _solve_dlt(eq.lines, T, S)
        if H is not None:
            out.append(("lines", H))
    base = np.vstack([eq.lines] + eq.points) if eq.points else eq.lines
    if eq.points:
        H = _solve_dlt(base, T, S)
        if H is not None:
            out.append(("lines + poles", H))
    pairs = eq.pairs[:max_ambiguous]
    for mask in range(2 ** len(pairs)):
        extra = [pr[(mask >> b) & 1] for b, pr in enumerate(pairs)]
        H = _solve_dlt(np.vstack([base] + extra), T, S) if extra else None
        if H is not None:
            out.append((f"lines + conic {mask}", H))
    return out


def camera_from_homography(H: np.ndarray, principal_point: np.ndarray) -> tuple[float, np.ndarray, np.ndarray] | None:
    """Focal length, rotation and centre from a ground-to-image homography (square pixels, known
    principal point).

    With ``A = T^-1 H`` (``T`` the principal-point translation), ``A ~ diag(f, f, 1) [r1 r2 t]``; the
    constraints ``r1 . r2 = 0`` and ``|r1| = |r2|`` are linear in ``1 / f^2`` and solved together in
    the least-squares sense (Zhang 2000, section 3.1). The overall sign is chosen so that the camera
    stands above the ground; ``R`` is the nearest rotation to ``[r1 r2 r1 x r2]``.

    Args:
        H: (3, 3) ground (x, y, 1) metres -> pixels. principal_point: (2,) px.

    Returns:
        ``(f px, R (3, 3) world to camera, C (3,) metres)`` or ``None`` when no positive focal
        length fits or the camera would stand below the ground.
    """
    T_inv = np.array([[1, 0, -principal_point[0]], [0, 1, -principal_point[1]], [0, 0, 1]], dtype=float)
    A = T_inv @ H
    h1, h2 = A[:, 0], A[:, 1]
    # r1.r2 = 0: (h11 h12 + h21 h22) / f^2 + h31 h32 = 0
    # |r1| = |r2|: (h11^2 + h21^2 - h12^2 - h22^2) / f^2 + h31^2 - h32^2 = 0
    m = np.array([h1[0] * h2[0] + h1[1] * h2[1], h1[0] ** 2 + h1[1] ** 2 - h2[0] ** 2 - h2[1] ** 2])
    c = np.array([h1[2] * h2[2], h1[2] ** 2 - h2[2] ** 2])
    denom = float(m @ m)
    if denom <= 0:
        return None
    inv_f2 = -float(m @ c) / denom
    if not inv_f2 > 0:
        return None
    f = 1.0 / np.sqrt(inv_f2)
    B = np.diag([1 / f, 1 / f, 1.0]) @ A
    lam = 2.0 / (np.linalg.norm(B[:, 0]) + np.linalg.norm(B[:, 1]))
    B = B * lam
    # The two signs of lambda give mirror images of the camera through the ground plane (C_z and
    # -C_z); keep the one above the ground (z points down, so C_z < 0).
    for sign in (1.0, -1.0):
        r1, r2, t = sign * B[:, 0], sign * B[:, 1], sign * B[:, 2]
        M = np.stack([r1, r2, _cross3(r1, r2)], axis=1)
        u, _, vt = np.linalg.svd(M)
        R = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
        C = -R.T @ t
        if np.all(np.isfinite(C)) and C[2] < 0:
            break
    else:
        return None
    return float(f), R, C




def labelled_target(obs: Observations) -> np.ndarray:
    """A world point (3,) the camera probably looks at: the mean of the labelled elements' anchors.

    Anchors are the world intersections of labelled perpendicular ground elements (corners that the
    view likely contains), circle centres, and goal centres; the mean of segment midpoints when
    none of those exists.
    """
    anchors: list[np.ndarray] = []
    ground = [(a, b) for c, a, b in zip(obs.seg_classes, obs.seg_a, obs.seg_b, strict=True) if c not in GOAL_CLASSES]
    for i in range(len(ground)):
        for j in range(i + 1, len(ground)):
            (a1, b1), (a2, b2) = ground[i], ground[j]
            d1, d2 = b1 - a1, b2 - a2
            if abs(d1[:2] @ d2[:2]) > 1e-6 * np.linalg.norm(d1) * np.linalg.norm(d2):
                continue  # parallel
            # Intersection of the two axis-aligned lines.
            if abs(d1[0]) > abs(d1[1]):
                anchors.append(np.array([a2[0], a1[1], 0.0]))
            else:
                anchors.append(np.array([a1[0], a2[1], 0.0]))
    for c in obs.circle_centre:
        anchors.append(np.array([c[0], c[1], 0.0]))
    for c, a, _b in zip(obs.seg_classes, obs.seg_a, obs.seg_b, strict=True):
        if c in GOAL_CLASSES:
            anchors.append(np.array([a[0], 0.0, 0.0]))
    if not anchors:
        anchors = [0.5 * (a + b) for a, b in zip(obs.seg_a, obs.seg_b, strict=True)]
    if not anchors:
        return np.zeros(3)
    t = np.mean(anchors, axis=0)
    t[2] = 0.0
    return t


def anchor_correspondences(obs: Observations, scale_px: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Image points whose world point is known, derived from the labels alone (no camera needed).

    * Where two labelled ground lines that are perpendicular on the pitch meet: the crossing of
      their fitted image lines is the image of the world corner (exact, projective).
    * A labelled circle with 5 points or more: the centre of its fitted image conic
      (:func:`fit_conic`) <-> the circle's centre (approximate: perspective moves the image of a
      circle's centre off the ellipse's centre, by little at broadcast distances).
    * A labelled goal element: the centroid of its points <-> the middle of the goal mouth on the
      ground (approximate).

    Args:
        obs: the frame's observations. scale_px: image scale (px) used to condition the fits.

    Returns:
        ``[(uv (2,) px, X (3,) world metres)]``, possibly empty.
    """
    out: list[tuple[np.ndarray, np.ndarray]] = []
    ground: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (a, b, image line in pixels)
    for i, (c, a, b) in enumerate(zip(obs.seg_classes, obs.seg_a, obs.seg_b, strict=True)):
        pts = obs.seg_points[obs.seg_index == i]
        if c in GOAL_CLASSES:
            out.append((pts.mean(axis=0), np.array([a[0], 0.0, 0.0])))
            continue
        if len(pts) >= 2 and np.ptp(pts, axis=0).max() >= 1.0:
            li = _fit_image_line(pts)
            if li is not None:
                ground.append((a, b, li))
    for i in range(len(ground)):
        for j in range(i + 1, len(ground)):
            (a1, b1, l1), (a2, b2, l2) = ground[i], ground[j]
            d1, d2 = (b1 - a1)[:2], (b2 - a2)[:2]
            if abs(d1 @ d2) > 1e-6 * np.linalg.norm(d1) * np.linalg.norm(d2):
                continue  # not perpendicular on the pitch (parallel: no crossing)
            p = _cross3(l1, l2)
            if abs(p[2]) < 1e-12 * np.linalg.norm(p[:2]):
                continue
            uv = p[:2] / p[2]
            if np.max(np.abs(uv)) > 1e3 * scale_px:
                continue  # the image lines are nearly parallel: the crossing is meaningless
            corner = np.array([a2[0], a1[1], 0.0]) if abs(d1[0]) > abs(d1[1]) else np.array([a1[0], a2[1], 0.0])
            out.append((uv, corner))
    for j in range(len(obs.circle_classes)):
        pts = obs.circle_points[obs.circle_index == j]
        conic = fit_conic(pts / scale_px) if len(pts) >= 5 else None
        if conic is None:
            centre = pts.mean(axis=0)
        else:
            try:
                fitted = np.linalg.solve(conic[:2, :2], -conic[:2, 2]) * scale_px
            except np.linalg.LinAlgError:
                fitted = pts.mean(axis=0)
            # A partial arc can fit a wild ellipse: keep its centre only near the labelled points.
            spread = float(np.ptp(pts, axis=0).max())
            centre = (fitted if np.linalg.norm(fitted - pts.mean(axis=0)) <= 2.0 * spread + 1.0
                      else pts.mean(axis=0))
        cx, cy = obs.circle_centre[j]
        out.append((centre, np.array([cx, cy, 0.0])))
    return out


@njit(**JIT)
def _wahba(camera_dirs: np.ndarray, world_dirs: np.ndarray, weights: np.ndarray) -> np.ndarray:
    B = (camera_dirs * weights.reshape(-1, 1)).T @ world_dirs
    u, _, vt = np.linalg.svd(B)
    fix = np.eye(3)
    fix[2, 2] = np.linalg.det(u @ vt)
    return u @ fix @ vt


def wahba_rotation(camera_dirs: np.ndarray, world_dirs: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """The rotation ``R`` (world to camera) minimising ``sum w_i |c_i - R w_i|^2`` (Wahba's problem,
    solved by SVD as in Kabsch's algorithm; Markley 1988).

    Args:
        camera_dirs, world_dirs: (N, 3) unit vectors, N >= 2 not all parallel. weights: (N,) >= 0.

    Returns:
        (3, 3) proper rotation.

    >>> R = wahba_rotation(np.eye(3)[[1, 0, 2]], np.eye(3)[:3])
    >>> np.round(R @ [1.0, 0.0, 0.0], 6).tolist(), round(float(np.linalg.det(R)), 6)
    ([0.0, 1.0, 0.0], 1.0)
    """
    c = np.ascontiguousarray(camera_dirs, dtype=float)
    w = np.ones(len(c)) if weights is None else np.ascontiguousarray(weights, dtype=float)
    return _wahba(c, np.ascontiguousarray(world_dirs, dtype=float), w)


@njit(**JIT)
def _wahba_each(camera_dirs: np.ndarray, world_dirs: np.ndarray) -> np.ndarray:
    out = np.empty((camera_dirs.shape[0], 3, 3))
    weights = np.ones(world_dirs.shape[0])
    for k in range(camera_dirs.shape[0]):
        out[k] = _wahba(np.ascontiguousarray(camera_dirs[k]), world_dirs, weights)
    return out


def wahba_rotations(camera_dirs: np.ndarray, world_dirs: np.ndarray) -> np.ndarray:
    """:func:`wahba_rotation` (unit weights) of each set of camera directions ``camera_dirs`` (F, N, 3) onto the same
    world directions ``world_dirs`` (N, 3), unit vectors, in one compiled call: (F, 3, 3) proper rotations, each the
    very matrix :func:`wahba_rotation` gives (the same compiled solve; a series of focal hypotheses cost their calls,
    not their 3 x 3 SVDs).

    >>> cam = np.stack([np.eye(3)[[1, 0, 2]], np.eye(3)])
    >>> Rs = wahba_rotations(cam, np.eye(3))
    >>> bool(np.array_equal(Rs[0], wahba_rotation(cam[0], np.eye(3)))), Rs.shape
    (True, (2, 3, 3))
    """
    return _wahba_each(np.ascontiguousarray(camera_dirs, dtype=float), np.ascontiguousarray(world_dirs, dtype=float))


@njit(**JIT)
def _upright_rotations(uv: np.ndarray, world: np.ndarray, pp: np.ndarray, focals: np.ndarray, anchor_sigma_px: float,
                       roll_sigma_rad: float) -> np.ndarray:
    """:func:`fixed_centre_rotations` from the anchors' pixels ``uv`` (A, 2) and unit world directions
    ``world`` (A, 3) seen from the centre: (F, 3, 3)."""
    n = uv.shape[0]
    w_dirs = np.empty((n + 1, 3))
    w_dirs[:n] = world
    w_dirs[n, 0], w_dirs[n, 1], w_dirs[n, 2] = 0.0, 0.0, 1.0  # down
    cam = np.empty((n + 1, 3))
    weights = np.empty(n + 1)
    out = np.empty((focals.shape[0], 3, 3))
    for i in range(focals.shape[0]):
        f = focals[i]
        weights[:n] = (f / anchor_sigma_px) ** 2
        weights[n] = 1.0 / roll_sigma_rad**2
        for a in range(n):
            x, y = (uv[a, 0] - pp[0]) / f, (uv[a, 1] - pp[1]) / f
            norm = math.sqrt(x * x + y * y + 1.0)
            cam[a, 0], cam[a, 1], cam[a, 2] = x / norm, y / norm, 1.0 / norm
        # No-roll prior: the camera's x axis is horizontal, i.e. the world's down direction seen from
        # the camera, R (0, 0, 1), has no x component. As a Wahba pair: down <-> R down with its x
        # component removed, from the current estimate (a fixed point reached in a few rounds);
        # first guess: down is the image's y axis.
        cam[n, 0], cam[n, 1], cam[n, 2] = 0.0, 1.0, 0.0
        R = np.eye(3)
        for _ in range(4):
            R = _wahba(cam, w_dirs, weights)
            vy, vz = R[1, 2], R[2, 2]  # R down, its x component removed
            norm = math.sqrt(vy * vy + vz * vz)
            if norm < 1e-9:  # looking straight down: the roll is free
                break
            cam[n, 0], cam[n, 1], cam[n, 2] = 0.0, vy / norm, vz / norm
        out[i] = R
    return out


def fixed_centre_rotations(obs: Observations, centre: np.ndarray, principal_point: np.ndarray,
                           focals: np.ndarray, anchor_sigma_px: float = 2.0, roll_sigma_deg: float = 1.0
                           ) -> np.ndarray:
    """Starting rotations of a camera whose centre is known (the game's rig), one per focal length.

    With the centre ``C`` known, each labelled image point ``uv`` whose world point ``X`` is known
    (:func:`anchor_correspondences`) gives a pair of directions: its ray in the camera,
    ``K^-1 (uv, 1)`` (depends on the focal length ``f``), and ``X - C`` in the world; the labels'
    image centroid is paired with the mean of those world points. The rotation is the Wahba/Kabsch
    fit of these pairs (:func:`wahba_rotation`), together with the broadcast prior of an upright
    camera (no roll: the camera's x axis is horizontal). Each pair is weighted by its inverse
    variance (squared angles): an anchor by ``(f / anchor_sigma_px)^2``, the prior by
    ``1 / roll_sigma^2``, so anchors spread over the image fix the roll themselves and the prior
    decides only what they leave free (the roll about a single anchor's ray, as in TRIAD). Unlike
    pointing the optical axis at the labelled part of the pitch, this puts each anchor where the
    labels show it in the image, which matters for a zoomed view whose labels sit off-centre.

    Args:
        obs: the frame's observations.
        centre: (3,) camera centre, world metres (z down, above the ground).
        principal_point: (2,) px. focals: (F,) focal length hypotheses, px.
        anchor_sigma_px: uncertainty of an anchor's image position, px (label noise, and the
            offset of a circle's image centre from its ellipse's centre).
        roll_sigma_deg: spread of broadcast cameras' roll, degrees.

    Returns:
        (F, 3, 3) world-to-camera rotations; empty (0, 3, 3) when the labels give no anchor or an
        anchor coincides with the centre.
    """
    centre = np.asarray(centre, dtype=float)
    focals = np.asarray(focals, dtype=float).reshape(-1)
    # The anchors depend on the labels only: computed once per observations and image scale (a frame
    # fitted at every position of its game's rig asks for them at each position).
    scale_px = float(2.0 * principal_point[0] + 1.0)
    cache = obs.__dict__.setdefault("_anchor_correspondences", {})  # as functools.cached_property stores
    if scale_px not in cache:
        cache[scale_px] = anchor_correspondences(obs, scale_px)
    pairs = cache[scale_px]
    if not pairs:
        return np.zeros((0, 3, 3))
    uv = np.array([p for p, _ in pairs])
    world = np.array([x for _, x in pairs]) - centre
    norms = np.linalg.norm(world, axis=1)
    if np.any(norms < 1e-6):
        return np.zeros((0, 3, 3))
    world /= norms[:, None]
    return _upright_rotations(np.ascontiguousarray(uv, dtype=float), np.ascontiguousarray(world),
                              np.ascontiguousarray(principal_point, dtype=float), np.ascontiguousarray(focals),
                              float(anchor_sigma_px), float(np.radians(roll_sigma_deg)))
