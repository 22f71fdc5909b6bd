"""Pinhole camera with SoccerNet's distortion model, and its SoccerNet-calibration JSON form.

Conventions (method.md sections 1-2):

* world frame: SoccerNet, metres, origin at the centre spot, z points down;
* ``x_cam = R (X - C)`` with ``R`` world-to-camera and ``C`` the camera centre; ``P = K R [I | -C]``
  (paper Eq. projection);
* image: pixels, origin at the top-left corner, x right, y down. v3d uses **continuous** pixel
  coordinates (the top-left pixel covers [0, 1) x [0, 1)); cameras carry their own principal point,
  so the (W - 1) / 2 convention of PnLCalib cameras and the W / 2 one of the synthetic data both work;
* ``R = (Rz(pan) Rx(tilt) Rz(roll))^T`` (SoccerNet ``src/camera.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Mapping

import numpy as np

#: Points closer than this to the camera plane (camera z, metres) do not project (SoccerNet uses 1e-3).
MIN_DEPTH_M = 1e-3

_JSON_FIELDS = (
    "pan_degrees", "tilt_degrees", "roll_degrees", "x_focal_length", "y_focal_length",
    "principal_point", "position_meters",
)


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_from_pan_tilt_roll(pan_deg: float, tilt_deg: float, roll_deg: float) -> np.ndarray:
    """World-to-camera rotation from SoccerNet's pan, tilt and roll.

    ``R = (Rz(pan) Rx(tilt) Rz(roll))^T`` (SoccerNet ``src/camera.py``, ``pan_tilt_roll_to_orientation``).

    Args:
        pan_deg, tilt_deg, roll_deg: angles in degrees.

    Returns:
        (3, 3) rotation matrix, world to camera.

    >>> R = rotation_from_pan_tilt_roll(0.0, 90.0, 0.0)
    >>> (np.round(R @ np.array([0.0, -1.0, 0.0]), 6) + 0.0).tolist()  # looking along -y: the optical axis
    [0.0, 0.0, 1.0]
    """
    pan, tilt, roll = np.radians([pan_deg, tilt_deg, roll_deg])
    return (_rz(pan) @ _rx(tilt) @ _rz(roll)).T


def look_at_rotation(centre: np.ndarray, target: np.ndarray, roll_deg: float = 0.0) -> np.ndarray:
    """World-to-camera rotation of a camera at ``centre`` whose optical axis passes through ``target``.

    The image x axis stays horizontal (then rolled about the optical axis so that the camera's
    SoccerNet ``roll_degrees`` is ``roll_deg``) and the image y axis follows the world's downward
    direction (+z) as seen from the camera, as a broadcast head on a level tripod.

    Args:
        centre: (3,) camera centre, world metres (SoccerNet, z down).
        target: (3,) world point on the optical axis, metres.
        roll_deg: SoccerNet roll (rotation about the optical axis), degrees.

    Returns:
        (3, 3) rotation ``R`` with ``x_cam = R (X - C)``.

    Raises:
        ValueError: the two points coincide, or the camera would look straight up or down.

    >>> R = look_at_rotation(np.array([0.0, 50.0, -10.0]), np.array([0.0, 0.0, -10.0]))
    >>> (np.round(R @ np.array([0.0, -1.0, 0.0]), 6) + 0.0).tolist()  # the optical axis is camera z
    [0.0, 0.0, 1.0]
    """
    z = np.asarray(target, float).reshape(3) - np.asarray(centre, float).reshape(3)
    n = np.linalg.norm(z)
    if n < 1e-9:
        raise ValueError("look_at_rotation: target equals centre")
    z = z / n
    down = np.array([0.0, 0.0, 1.0])
    y = down - (down @ z) * z
    ny = np.linalg.norm(y)
    if ny < 1e-9:
        raise ValueError("look_at_rotation: a camera looking straight up or down has no horizontal image axis")
    y = y / ny
    R = np.stack([np.cross(y, z), y, z])
    # SoccerNet's R = (Rz(pan) Rx(tilt) Rz(roll))^T ends with Rz(roll)^T = Rz(-roll) on the left.
    return _rz(-np.radians(roll_deg)) @ R if roll_deg else R


def pan_tilt_roll_from_rotation(rotation: np.ndarray) -> tuple[float, float, float]:
    """Pan, tilt and roll (degrees) of a world-to-camera rotation.

    Of the two solutions SoccerNet keeps the one with the smaller |roll|
    (``rotation_matrix_to_pan_tilt_roll`` in SoccerNet ``src/camera.py``).

    Args:
        rotation: (3, 3) world-to-camera rotation.

    Raises:
        ValueError: not a (3, 3) array.

    >>> R = rotation_from_pan_tilt_roll(30.0, 80.0, -2.0)
    >>> [round(a, 6) for a in pan_tilt_roll_from_rotation(R)]
    [30.0, 80.0, -2.0]
    """
    rot = np.asarray(rotation, dtype=float)
    if rot.shape != (3, 3):
        raise ValueError(f"rotation must be (3, 3), got {rot.shape}")
    o = rot.T
    best = None
    for tilt in (np.arccos(np.clip(o[2, 2], -1.0, 1.0)), -np.arccos(np.clip(o[2, 2], -1.0, 1.0))):
        sign = 1.0 if np.sin(tilt) > 0.0 else -1.0
        pan = np.arctan2(sign * o[0, 2], sign * -o[1, 2])
        roll = np.arctan2(sign * o[2, 0], sign * o[2, 1])
        if best is None or abs(roll) < abs(best[2]):
            best = (pan, tilt, roll)
    assert best is not None
    return tuple(float(np.degrees(a)) for a in best)  # type: ignore[return-value]  # best holds three angles


@dataclass(frozen=True)
class Camera:
    """A calibrated camera (SoccerNet model).

    Attributes:
        K: (3, 3) intrinsics ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, pixels, fx and fy positive.
        R: (3, 3) rotation, world to camera.
        C: (3,) camera centre in the world frame, metres (z negative above the ground).
        radial: (6,) k1..k6 of the rational radial model.
        tangential: (2,) p1, p2.
        thin_prism: (4,) s1..s4.
    """

    K: np.ndarray
    R: np.ndarray
    C: np.ndarray
    radial: np.ndarray = field(default_factory=lambda: np.zeros(6))
    tangential: np.ndarray = field(default_factory=lambda: np.zeros(2))
    thin_prism: np.ndarray = field(default_factory=lambda: np.zeros(4))

    def __post_init__(self) -> None:
        for name, shape in (("K", (3, 3)), ("R", (3, 3)), ("C", (3,)), ("radial", (6,)),
                            ("tangential", (2,)), ("thin_prism", (4,))):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.shape != shape:
                raise ValueError(f"Camera.{name} must have shape {shape}, got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"Camera.{name} has non-finite values")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if not (self.K[0, 0] > 0 and self.K[1, 1] > 0):
            raise ValueError(f"Camera.K must have positive focal lengths, got fx={self.K[0, 0]!r}, fy={self.K[1, 1]!r}")

    # ----- construction -------------------------------------------------------------------------
    @classmethod
    def from_parameters(
        cls, *, focal_px: float | tuple[float, float], principal_point: tuple[float, float],
        pan_deg: float, tilt_deg: float, roll_deg: float, position_m: np.ndarray,
    ) -> "Camera":
        """Build an undistorted camera from focal length(s), principal point (px), angles (degrees)
        and centre (world, metres).

        Raises:
            ValueError: a non-positive focal length, or non-finite values.
        """
        fx, fy = (focal_px, focal_px) if np.isscalar(focal_px) else focal_px  # type: ignore[misc]  # a focal that is not a scalar is a pair
        K = np.array([[fx, 0.0, principal_point[0]], [0.0, fy, principal_point[1]], [0.0, 0.0, 1.0]])
        return cls(K=K, R=rotation_from_pan_tilt_roll(pan_deg, tilt_deg, roll_deg), C=np.asarray(position_m, float))

    @classmethod
    def from_soccernet(cls, data: Mapping[str, Any]) -> "Camera":
        """Camera from a SoccerNet-calibration JSON object (method.md section 2).

        R is rebuilt from pan/tilt/roll and ``rotation_matrix`` is ignored, as SoccerNet's
        ``Camera.from_json_parameters`` does. Missing distortion arrays mean no distortion.

        Raises:
            ValueError: a required field is missing or malformed (the message names it).
        """
        missing = [f for f in _JSON_FIELDS if f not in data]
        if missing:
            raise ValueError(f"camera JSON lacks field(s): {', '.join(missing)}")
        try:
            pp = [float(v) for v in data["principal_point"]]
            pos = np.array([float(v) for v in data["position_meters"]])
            if len(pp) != 2 or pos.shape != (3,):
                raise ValueError
            fx, fy = float(data["x_focal_length"]), float(data["y_focal_length"])
            angles = [float(data[k]) for k in ("pan_degrees", "tilt_degrees", "roll_degrees")]
        except (TypeError, ValueError) as exc:
            raise ValueError("camera JSON: principal_point must be 2 numbers, position_meters 3, "
                             "focal lengths and angles numbers") from exc
        if not (fx > 0 and fy > 0):
            raise ValueError("camera JSON: x_focal_length and y_focal_length must be positive")
        K = np.array([[fx, 0.0, pp[0]], [0.0, fy, pp[1]], [0.0, 0.0, 1.0]])

        def arr(name: str, n: int) -> np.ndarray:
            v = np.array(data.get(name, [0.0] * n) or [0.0] * n, dtype=float)
            if v.shape != (n,):
                raise ValueError(f"camera JSON: {name} must hold {n} numbers")
            return v

        return cls(K=K, R=rotation_from_pan_tilt_roll(*angles), C=pos, radial=arr("radial_distortion", 6),
                   tangential=arr("tangential_distortion", 2), thin_prism=arr("thin_prism_distortion", 4))

    def to_soccernet(self) -> dict[str, Any]:
        """SoccerNet-calibration JSON object (method.md section 2), with ``rotation_matrix`` too.

        Skew, if any, is dropped (the format has none).
        """
        pan, tilt, roll = pan_tilt_roll_from_rotation(self.R)
        return {
            "pan_degrees": pan, "tilt_degrees": tilt, "roll_degrees": roll,
            "x_focal_length": float(self.K[0, 0]), "y_focal_length": float(self.K[1, 1]),
            "principal_point": [float(self.K[0, 2]), float(self.K[1, 2])],
            "position_meters": [float(v) for v in self.C],
            "rotation_matrix": self.R.tolist(),
            "radial_distortion": self.radial.tolist(),
            "tangential_distortion": self.tangential.tolist(),
            "thin_prism_distortion": self.thin_prism.tolist(),
        }

    # ----- derived quantities -------------------------------------------------------------------
    @cached_property
    def has_distortion(self) -> bool:
        """True when any distortion coefficient is non-zero (computed once: the arrays are read-only)."""
        return bool(np.any(self.radial) or np.any(self.tangential) or np.any(self.thin_prism))

    @cached_property
    def projection_matrix(self) -> np.ndarray:
        """(3, 4) ``P = K R [I | -C]`` (paper Eq. projection), ignoring distortion; computed once, read-only
        (the camera's arrays never change)."""
        P = self.K @ self.R @ np.hstack([np.eye(3), -self.C[:, None]])
        P.setflags(write=False)
        return P

    @cached_property
    def K_inv(self) -> np.ndarray:
        """(3, 3) ``K^-1`` (pixels -> normalised camera coordinates), computed once, read-only."""
        Kinv = np.linalg.inv(self.K)
        Kinv.setflags(write=False)
        return Kinv

    def scaled(self, sx: float, sy: float | None = None) -> "Camera":
        """The same camera for an image resized by ``sx`` (and ``sy``) in pixels.

        Focal lengths, skew and principal point scale (continuous pixel coordinates). Used to
        express a camera at the evaluation resolution (method.md section 2).

        Raises:
            ValueError: a factor that is not a positive finite number.

        >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
        ...                              tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
        >>> cam.scaled(0.5).K.tolist()
        [[500.0, 0.0, 480.0], [0.0, 500.0, 270.0], [0.0, 0.0, 1.0]]
        """
        sy = sx if sy is None else sy
        if not (np.isfinite(sx) and np.isfinite(sy) and sx > 0 and sy > 0):
            raise ValueError(f"scale factors must be positive finite numbers, got {sx!r}, {sy!r}")
        S = np.diag([sx, sy, 1.0])
        return Camera(K=S @ self.K, R=self.R, C=self.C, radial=self.radial, tangential=self.tangential,
                      thin_prism=self.thin_prism)

    # ----- projection ---------------------------------------------------------------------------
    def points_in_camera(self, points_world: np.ndarray) -> np.ndarray:
        """World points (N, 3) or (3,) metres -> camera-frame points (N, 3) metres (z is depth).

        Raises:
            ValueError: not (N, 3) or (3,).
        """
        X = as_points(points_world, 3, "points_world")
        return (X - self.C) @ self.R.T

    def distort(self, xy: np.ndarray) -> np.ndarray:
        """Apply SoccerNet's distortion (``Camera.distort``) to normalised image points.

        Args:
            xy: (N, 2) undistorted normalised coordinates (camera x/z, y/z).

        Returns:
            (N, 2) distorted normalised coordinates, float64 (SoccerNet casts to float32; the JaC
            module does that itself).
        """
        p = as_points(xy, 2, "xy")
        if not self.has_distortion:
            return p.copy()
        x, y = p[:, 0], p[:, 1]
        r2 = x * x + y * y
        k, t, s = self.radial, self.tangential, self.thin_prism
        factor = (1 + k[0] * r2 + k[1] * r2**2 + k[2] * r2**3) / (1 + k[3] * r2 + k[4] * r2**2 + k[5] * r2**3)
        xd = x * factor + 2 * t[0] * x * y + t[1] * (r2 + 2 * x * x) + s[0] * r2 + s[1] * r2**2
        yd = y * factor + 2 * t[1] * x * y + t[0] * (r2 + 2 * y * y) + s[2] * r2 + s[3] * r2**2
        return np.stack([xd, yd], axis=1)

    def undistort(self, xy_distorted: np.ndarray, iterations: int = 20) -> np.ndarray:
        """Invert :meth:`distort` by fixed-point iteration (exact when there is no distortion).

        Args:
            xy_distorted: (N, 2) distorted normalised coordinates.

        Returns:
            (N, 2) undistorted normalised coordinates.
        """
        d = as_points(xy_distorted, 2, "xy_distorted")
        if not self.has_distortion:
            return d.copy()
        u = d.copy()
        for _ in range(iterations):
            u = u + (d - self.distort(u))
        return u

    def project(self, points_world: np.ndarray, distort: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Project world points into the image.

        Args:
            points_world: (N, 3) or (3,) world points, metres.
            distort: apply the distortion model.

        Returns:
            ``(uv, in_front)``: (N, 2) pixel coordinates and (N,) bool, False for points with depth
            below :data:`MIN_DEPTH_M` (their ``uv`` is NaN).

        >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
        ...                              tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
        >>> uv, ok = cam.project(np.array([[0.0, 0.0, -10.0]]))
        >>> np.round(uv, 6).tolist(), ok.tolist()
        ([[960.0, 540.0]], [True])
        """
        Xc = self.points_in_camera(points_world)
        z = Xc[:, 2]
        in_front = z > MIN_DEPTH_M
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = Xc[:, :2] / np.where(in_front, z, np.nan)[:, None]
        if distort and self.has_distortion:
            xy = self.distort(xy)
        uv = xy @ self.K[:2, :2].T + self.K[:2, 2]
        return uv, in_front

    def project_in_front(self, points_world: np.ndarray) -> np.ndarray | None:
        """:meth:`project` (with distortion) of world points (N, 3) metres all in front of the camera: their (N, 2)
        pixels, the same numbers :meth:`project` gives, or None when any lies at a depth below :data:`MIN_DEPTH_M`.
        Without :meth:`project`'s shape checks and NaN handling, for the few points a Jacobian projects many times an
        edit (``app.geometry.spread.projection_jacobian``).

        Raises:
            ValueError, IndexError: ``points_world`` not (N, 3) (numpy's own message: no check of its own).
        """
        Xc = (points_world - self.C) @ self.R.T
        z = Xc[:, 2]
        if not (z > MIN_DEPTH_M).all():
            return None
        xy = Xc[:, :2] / z[:, None]  # every divisor in front: what project's divide by np.where(in_front, z, nan) gives
        if self.has_distortion:
            xy = self.distort(xy)
        return xy @ self.K[:2, :2].T + self.K[:2, 2]

    def normalise_pixels(self, uv: np.ndarray, undistort: bool = True) -> np.ndarray:
        """Pixels (N, 2) -> undistorted normalised coordinates (N, 2) (``K^-1`` then undistortion).

        Args:
            uv: (N, 2) or (2,) pixel coordinates of this camera's image.
            undistort: invert the distortion model (:meth:`undistort`) after ``K^-1``.

        Returns:
            (N, 2) normalised camera coordinates (camera x/z, y/z).

        Raises:
            ValueError: ``uv`` not (N, 2) or (2,).
        """
        p = as_points(uv, 2, "uv")
        Kinv = self.K_inv
        xy = p @ Kinv[:2, :2].T + Kinv[:2, 2]
        return self.undistort(xy) if undistort else xy

    def rays(self, uv: np.ndarray, undistort: bool = True) -> np.ndarray:
        """Back-project pixels to unit ray directions in the world frame.

        Args:
            uv: (N, 2) or (2,) pixel coordinates.
            undistort: undistort the pixels first (:meth:`normalise_pixels`).

        Returns:
            (N, 3) unit vectors (world frame); each ray starts at :attr:`C`.

        Raises:
            ValueError: ``uv`` not (N, 2) or (2,).
        """
        xy = self.normalise_pixels(uv, undistort=undistort)
        d_cam = np.hstack([xy, np.ones((len(xy), 1))])
        d = d_cam @ self.R  # R^T d_cam, row-wise
        return d / np.linalg.norm(d, axis=1, keepdims=True)


def as_points(a: np.ndarray, dim: int, name: str) -> np.ndarray:
    """``a`` as a float (N, dim) array; a single point (dim,) becomes (1, dim).

    Values are not checked (NaN passes: projection marks such points, callers that need finite
    input check it themselves).

    Raises:
        ValueError: any other shape; the message names the argument ``name``.

    >>> as_points([1.0, 2.0], 2, "uv").shape
    (1, 2)
    """
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1 and arr.shape[0] == dim:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ValueError(f"{name} must have shape (N, {dim}), got {np.shape(a)}")
    return arr
