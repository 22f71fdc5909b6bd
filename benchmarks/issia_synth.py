"""ISSIA-like synthetic sequences of any length and seed, with their truth (for ``benchmarks/issia.py``).

Usage::

    python -m benchmarks.issia_synth OUT_DIR [--seconds 60] [--seed 1] [--truth FILE]
                                             [--cameras issia_calibration.json] [--lines issia_lines.json]

writes ``OUT_DIR/issia_calibration.json``, ``OUT_DIR/issia_lines.json`` (copied), ``OUT_DIR/ball_points.csv``
(no videos) and the truth, by default ``OUT_DIR.truth.json`` beside the folder, as ``issia-dev`` and
``issia-dev.truth.json`` sit in ``../shared/data/synthetic``. Then
``python -m benchmarks.issia --data OUT_DIR --truth OUT_DIR.truth.json`` scores v3d on it.

The dev truth (``issia-dev.truth.json``) states the generator's parameters but not its code; this module
follows what it states and what its 200 frames show, and says below what it had to assume.

**Modelled as the dev truth states or shows** (checked against its frames):

* World and image conventions of method.md: metres, z down, ball centre at ``z = -0.11`` on the grass;
  continuous pixels of 1920x1080, principal point (960, 540); the six static dev cameras by default.
* Frame ``i`` is at ``t = i / 25`` s. A kick happens at a frame time; that frame still shows the ball
  before the kick (position = the kick's position, velocity the one before it), as in the dev frames
  114 and 182.
* Flight under ``g = 9.81`` (no drag, no spin). A bounce at ``z = -r`` keeps the horizontal velocity and
  turns the vertical one into ``-0.6`` times itself (dev frames 179-180).
* Rolling: the ball's centre at ``z = -r``; the speed drops by 1.5 m/s^2 along the velocity until it
  stops; then it rests (dev frames 0-114: ``|dv| = 0.06`` m/s per frame).
* A ground kick ("lofted": false) rolls from the start; its recorded velocity has a small upward part
  (dev kick 0: 2.9 degrees) that the motion ignores (dev frame 1 is at ``z = -0.11`` exactly).
* Kick speed in [8, 25] m/s, lofted with probability 0.45; with probability 0.6 the kick aims at a point
  in the least visited third of the pitch (thirds along x, by the frames the ball spent there so far),
  otherwise at a uniform point of the pitch. A receive (the next kick) takes the ball only when its centre
  is at most 2 m above the ground (``receive_max_height_m``; dev kick 2 is a volley at 0.77 m).
* ``center_px`` is the projection of the ball's centre; ``in_image`` is ``0 <= u < 1920 and 0 <= v < 1080``
  (no dev frame disagrees); ``d_true = 2 fy tan(asin(r / D))``; ``precise_box`` is the exact box of the
  ball's silhouette (its rim circle projected, with the camera's distortion) and
  ``precise_box_exact_center`` its centre.
* Labels: an in-image ball is occluded in runs (a two-state chain per camera: a run starts with
  probability ``p_occluded / mean_length`` per frame and ends with probability ``1 / mean_length``, so
  about ``p_occluded`` of the frames are occluded with runs of mean length 4; the dev sequence has 3 runs
  in 418 in-image frames, which rules out ``p_occluded`` as the per-frame start probability); an in-image,
  not occluded ball is annotated at ``center_px`` plus N(0, 0.7 px) per axis, rounded to 0.01 px (the
  CSV's precision); with probability 0.01 an annotated label is instead an outlier: a uniform point of
  the image at least 200 px from ``center_px`` (both dev outliers lie in the image, 368 and 911 px off).

**Assumed** (the dev truth does not say; each is a :class:`Physics` field and goes into the truth):

* The first kick is the kick-off at the centre spot at ``t = 0``.
* Lofted kicks: elevation uniform in [20, 45] degrees (dev: 31.8, 41.9), speed chosen to land on the
  target from the kick's height, clipped to the speed range. Ground kicks: horizontal speed
  ``sqrt(2 a d) * U(0.85, 1.3)`` for a target ``d`` metres away (the ball stops near it, mostly past it),
  clipped to the speed range; elevation U(0, 4) degrees, recorded only.
* The receive: the ball reaches the target at the time it passes closest to it (ground kick; when it
  stops short, the receiver runs to it at 5 m/s while it rests) or lands first (lofted). With
  probability ``p_uncontrolled`` (0.25) nobody takes it there: it runs on (bounces, rolls, maybe stops
  and rests) for an exponential time of mean 1.5 s more;
  otherwise the receive is ``U(-0.2, 0.4)`` s around that time (before a landing: a volley). At least
  0.4 s after the kick, at the first frame from then on where the ball is at most 2 m high. A ball that
  leaves the pitch (centre beyond a line by more than 1 m) is taken at the first such frame below 2 m
  (a restart, played from where it is).
* A bounce whose upward speed would be below 1.0 m/s ends the bouncing: the ball rolls on from there
  (hops below 5 cm are not modelled).
* Boards 4 m outside the lines, at any height: a ball that reaches them comes back, its velocity across
  them turned into -0.6 times itself (without them an uncontrolled ball flew up to 20 m out, among the
  cameras, in 1-2 % of the frames).
* Occlusion chains run over every frame (also out of the image); only in-image frames are reported
  occluded.

**Not modelled**: players, drag, spin, the ball's deformation, ground friction at a bounce, camera jitter
or rolling shutter, videos.

The truth JSON has the dev truth's keys (``generator, seed, fps, duration_s, image_size, video_size,
frame_numbering, conventions, physics, noise_model, cameras, kicks, summary, frames``) and ``events``
(bounces, starts of a roll after the last bounce, stops, hits of the boards, with time and position); each
kick also has its ``frame`` and ``target``. ``summary`` adds ``kicks_per_second``, ``lofted_kicks``,
``events`` (counts), ``phase_share`` (air / ground moving / ground at rest), ``frames_by_correct_labels`` and
``frames_ball_in_no_image``; ``summary.seconds`` is the generation's wall time (the dev value, 3.1, matches
no duration of its frames); ``coverage_1`` and ``coverage_2`` use a grid that reproduces the dev values
exactly (:func:`pitch_coverage`); ``video_size`` and ``video_bytes`` are ``null`` (no videos). Per frame,
each camera has the dev keys; ``motion_piece`` counts the motion pieces (a kick, a bounce and the start of
a roll after the last bounce each begin one; a stop does not); ``phase`` is ``"air"`` or ``"ground"``.

**Checked against the dev truth** (10 seeds x 60 s, mean; dev in brackets): in-image labels per frame 2.0
(2.09), occluded share of in-image frames 0.027 (0.014: 3 runs), outliers per annotated label 0.010
(0.005: 2 labels), kicks per second 0.37 (0.375), frames in the air 0.50 (0.42), frames with the ball in no
image 0.09 (0.135), frames with two or more correct labels 0.82 (0.845); 40 seeds x 8 s: per-camera
in-image shares 0.20 0.18 0.58 0.54 0.26 0.25 (0.12 0.17 0.29 0.74 0.24 0.52; the dev kick-off heads
towards cameras 4 and 6). ``coverage_2`` with the dev cameras: 0.916735..., equal to the dev value.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import shutil
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from app.datasets.issia import FPS
from app.geometry.camera import Camera

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "synthetic"
DEV_DIR = SHARED / "issia-dev"
CAMERA_IDS = ("1", "2", "3", "4", "5", "6")
PITCH_HALF = (52.5, 34.0)


@dataclass(frozen=True)
class Physics:
    """The ball's motion. The first seven fields are the dev truth's ``physics``; the rest are assumed."""

    g: float = 9.81
    restitution: float = 0.6
    rolling_deceleration: float = 1.5
    kick_speed_range: tuple[float, float] = (8.0, 25.0)
    p_lofted: float = 0.45
    p_target_least_visited_third: float = 0.6
    receive_max_height_m: float = 2.0
    # --- assumed (module docstring) ---
    ball_radius_m: float = 0.11
    loft_elevation_deg: tuple[float, float] = (20.0, 45.0)
    ground_elevation_deg: tuple[float, float] = (0.0, 4.0)
    ground_speed_margin: tuple[float, float] = (0.85, 1.3)
    receiver_speed_m_s: float = 5.0
    p_uncontrolled: float = 0.25
    uncontrolled_mean_s: float = 1.5
    receive_offset_s: tuple[float, float] = (-0.2, 0.4)
    min_kick_interval_s: float = 0.4
    min_bounce_speed: float = 1.0
    boards_m: float = 4.0
    target_margin_m: float = 3.0
    out_of_pitch_m: float = 1.0


@dataclass(frozen=True)
class NoiseModel:
    """The labels' noise: the dev truth's ``noise_model``."""

    point_sigma_px: float = 0.7
    p_occluded: float = 0.03
    occlusion_mean_length_frames: float = 4.0
    p_outlier: float = 0.01
    outlier_min_distance_px: float = 200.0


# ----------------------------------------------------------------------------------------------------
# motion: segments in closed form
# ----------------------------------------------------------------------------------------------------

@dataclass
class Segment:
    """A stretch of free motion from ``t0`` (s) to ``t1`` (``inf``: until a kick).

    ``kind``: ``"air"`` (``p0 + v0 t + (0, 0, g t^2 / 2)``) or ``"ground"`` (centre at ``z = -r``, speed
    falling by ``a`` along ``v0`` until it stops, then at rest). ``piece``: the truth's ``motion_piece``;
    ``start``: what began it (``kick``, ``bounce``, ``roll`` after the last bounce, ``wall``: the boards).
    """

    kind: str
    t0: float
    p0: np.ndarray
    v0: np.ndarray
    t1: float
    piece: int
    start: str = "kick"

    def state(self, t: float, ph: Physics) -> tuple[np.ndarray, np.ndarray]:
        """(position, velocity) at absolute time ``t`` (metres, m/s)."""
        s = t - self.t0
        if self.kind == "air":
            p = self.p0 + self.v0 * s + np.array([0.0, 0.0, 0.5 * ph.g * s * s])
            return p, self.v0 + np.array([0.0, 0.0, ph.g * s])
        speed = float(np.linalg.norm(self.v0[:2]))
        if speed < 1e-12:
            return self.p0.copy(), np.zeros(3)
        u = np.array([self.v0[0], self.v0[1], 0.0]) / speed
        s = min(s, speed / ph.rolling_deceleration)
        v = max(speed - ph.rolling_deceleration * s, 0.0)
        return self.p0 + u * (speed * s - 0.5 * ph.rolling_deceleration * s * s), u * v


def _wall_time(p: np.ndarray, v: np.ndarray, ph: Physics, roll: bool) -> tuple[float, int]:
    """(seconds until the ball's centre reaches the boards, axis 0 or 1 of the board it reaches), or
    ``(inf, -1)``: boards stand ``boards_m`` outside the lines. ``roll``: the ball decelerates along ``v``."""
    best, axis = np.inf, -1
    speed = float(np.hypot(v[0], v[1]))
    for i in (0, 1):
        if abs(v[i]) < 1e-12:
            continue
        wall = np.sign(v[i]) * (PITCH_HALF[i] + ph.boards_m)
        if abs(p[i]) >= abs(wall) and np.sign(p[i]) == np.sign(wall):
            continue  # already beyond (a kick from there): let it come back
        if roll:
            dist = (wall - p[i]) / v[i] * speed  # metres along the path
            a = ph.rolling_deceleration
            if dist > speed * speed / (2 * a):
                continue
            t = (speed - np.sqrt(max(speed * speed - 2 * a * dist, 0.0))) / a
        else:
            t = (wall - p[i]) / v[i]
        if 0 < t < best:
            best, axis = t, i
    return best, axis


def free_motion(t0: float, p0: np.ndarray, v0: np.ndarray, lofted: bool, piece: int, ph: Physics,
                horizon_s: float = 120.0) -> list[Segment]:
    """The ball's motion after a kick at ``t0`` from ``p0`` with velocity ``v0`` when nobody touches it:
    flights and bounces, then a roll that stops, then rest, with reflections off the boards (segments up
    to ``t0 + horizon_s``; each segment's ``start`` says what began it)."""
    r = ph.ball_radius_m
    segs: list[Segment] = []
    p, v, t = np.asarray(p0, float).copy(), np.asarray(v0, float).copy(), t0
    in_air = lofted or p[2] < -r - 1e-6
    if not in_air:
        p[2], v = -r, np.array([v[0], v[1], 0.0])
    start = "kick"
    while t < t0 + horizon_s:
        if in_air:
            # z(s) = p_z + v_z s + g s^2 / 2 = -r, the later root
            a, b, c = 0.5 * ph.g, v[2], p[2] + r
            land = (-b + np.sqrt(max(b * b - 4 * a * c, 0.0))) / (2 * a)
            hit, axis = _wall_time(p, v, ph, roll=False)
            s = min(land, hit)
            seg = Segment("air", t, p, v, t + s, piece, start)
            segs.append(seg)
            p, v = seg.state(t + s, ph)
            t += s
            piece += 1
            if hit < land:
                v[axis] = -ph.restitution * v[axis]
                start = "wall"
                continue
            p[2] = -r
            up = ph.restitution * v[2]
            if up < ph.min_bounce_speed:
                v = np.array([v[0], v[1], 0.0])
                in_air, start = False, "roll"
            else:
                v = np.array([v[0], v[1], -up])
                start = "bounce"
        else:
            hit, axis = _wall_time(p, v, ph, roll=True)
            seg = Segment("ground", t, p, v, t + hit, piece, start)
            segs.append(seg)
            if not np.isfinite(hit):
                break
            p, v = seg.state(t + hit, ph)
            t += hit
            piece += 1
            v[axis] = -ph.restitution * v[axis]
            start = "wall"
    return segs


def state_at(segs: list[Segment], t: float, ph: Physics) -> tuple[np.ndarray, np.ndarray, Segment]:
    """(position, velocity, segment) of the motion ``segs`` at time ``t``."""
    for seg in segs:
        if t < seg.t1 or seg is segs[-1]:
            p, v = seg.state(t, ph)
            return p, v, seg
    raise AssertionError("unreachable")


# ----------------------------------------------------------------------------------------------------
# kicks
# ----------------------------------------------------------------------------------------------------

def _target(rng: np.random.Generator, visits: np.ndarray, ph: Physics) -> np.ndarray:
    """A kick's target on the pitch: in the least visited third (probability ``p_target_least_visited_third``,
    ties drawn at random) or anywhere, ``target_margin_m`` inside the lines."""
    hx, hy = PITCH_HALF[0] - ph.target_margin_m, PITCH_HALF[1] - ph.target_margin_m
    if rng.random() < ph.p_target_least_visited_third:
        least = np.flatnonzero(visits == visits.min())
        third = int(rng.choice(least))
        lo = -PITCH_HALF[0] + third * 35.0
        x = rng.uniform(max(lo, -hx), min(lo + 35.0, hx))
    else:
        x = rng.uniform(-hx, hx)
    return np.array([x, rng.uniform(-hy, hy)])


def _kick_velocity(rng: np.random.Generator, p: np.ndarray, target: np.ndarray, lofted: bool,
                   ph: Physics) -> np.ndarray:
    """The kick's velocity (module docstring: elevation, speed to reach ``target``, clipped)."""
    d_vec = target - p[:2]
    d = float(np.linalg.norm(d_vec))
    u = d_vec / d if d > 1e-9 else np.array([1.0, 0.0])
    lo, hi = ph.kick_speed_range
    if lofted:
        th = np.radians(rng.uniform(*ph.loft_elevation_deg))
        rise = (-p[2]) - ph.ball_radius_m  # height of the centre above its landing height, >= 0
        denom = 2.0 * np.cos(th) ** 2 * (d * np.tan(th) + rise)
        s = np.sqrt(ph.g * d * d / denom) if denom > 1e-9 else lo
    else:
        th = np.radians(rng.uniform(*ph.ground_elevation_deg))
        s = np.sqrt(2.0 * ph.rolling_deceleration * d) * rng.uniform(*ph.ground_speed_margin) / np.cos(th)
    s = float(np.clip(s, lo, hi))
    return np.array([u[0] * s * np.cos(th), u[1] * s * np.cos(th), -s * np.sin(th)])


def _receive_frame(rng: np.random.Generator, segs: list[Segment], kick_frame: int, target: np.ndarray,
                   lofted: bool, fps: float, last_frame: int, ph: Physics) -> int:
    """The frame of the next kick after a kick at ``kick_frame`` (module docstring), or ``last_frame + 1``."""
    t_k = kick_frame / fps
    if lofted or segs[0].kind == "air":
        t_reach = segs[0].t1  # first landing
    else:
        g = segs[0]
        speed = float(np.linalg.norm(g.v0[:2]))
        t_stop = g.t0 + speed / ph.rolling_deceleration if speed > 0 else g.t0
        u = g.v0[:2] / speed if speed > 0 else np.zeros(2)
        along = float((target - g.p0[:2]) @ u)  # distance along the path to the point closest to the target
        reach = speed ** 2 / (2 * ph.rolling_deceleration)  # where the roll stops, metres along its path
        if speed > 0 and 0 < along < reach:
            a = ph.rolling_deceleration
            t_reach = g.t0 + (speed - np.sqrt(speed * speed - 2 * a * along)) / a
        elif along > 0:  # the ball stops short: the receiver runs to it
            t_reach = t_stop + (along - reach) / ph.receiver_speed_m_s
        else:
            t_reach = g.t0
        t_reach = min(t_reach, g.t1)  # the boards came first
    if rng.random() < ph.p_uncontrolled:
        t_recv = t_reach + rng.exponential(ph.uncontrolled_mean_s)
    else:
        t_recv = t_reach + rng.uniform(*ph.receive_offset_s)
    t_recv = max(t_recv, t_k + ph.min_kick_interval_s)
    f_recv = int(np.ceil(t_recv * fps - 1e-9))
    first = kick_frame + max(1, int(np.ceil(ph.min_kick_interval_s * fps - 1e-9)))
    for f in range(first, last_frame + 1):
        p, _, _ = state_at(segs, f / fps, ph)
        low = -p[2] <= ph.receive_max_height_m
        out = abs(p[0]) > PITCH_HALF[0] + ph.out_of_pitch_m or abs(p[1]) > PITCH_HALF[1] + ph.out_of_pitch_m
        if low and (f >= f_recv or out):
            return f
    return last_frame + 1


def simulate(n_frames: int, fps: float, rng: np.random.Generator, ph: Physics
             ) -> tuple[list[dict], list[dict], list[dict]]:
    """The ball over ``n_frames`` frames: (kicks in the dev truth's format, events, per-frame states
    ``{frame, t, ball_3d, ball_velocity, phase, motion_piece}``). Events are what happened between kicks:
    ``{"kind": "bounce" | "roll" | "stop" | "wall", "t", "position"}`` (``roll``: the last bounce, after
    which the ball rolls; ``stop``: a roll comes to rest; ``wall``: the ball hits the boards)."""
    third_visits = np.zeros(3)
    kicks: list[dict] = []
    events: list[dict] = []
    frames: list[dict] = []
    p = np.array([0.0, 0.0, -ph.ball_radius_m])
    kick_frame, piece = 0, 0
    while kick_frame < n_frames:
        lofted = bool(rng.random() < ph.p_lofted)
        target = _target(rng, third_visits, ph)
        v = _kick_velocity(rng, p, target, lofted, ph)
        kicks.append({"t": round(kick_frame / fps, 6), "frame": kick_frame, "position": [round(float(x), 4) for x in p],
                      "velocity": [round(float(x), 4) for x in v], "speed": round(float(np.linalg.norm(v)), 3),
                      "lofted": lofted, "target": [round(float(x), 3) for x in target]})
        segs = free_motion(kick_frame / fps, p, v, lofted, piece, ph)
        nxt = _receive_frame(rng, segs, kick_frame, target, lofted, fps, n_frames - 1, ph)
        t_next = min(nxt, n_frames) / fps
        for seg in segs[1:]:
            if seg.t0 < t_next:
                events.append({"kind": seg.start, "t": round(seg.t0, 6),
                               "position": [round(float(x), 4) for x in seg.p0]})
        for seg in segs:
            speed = float(np.linalg.norm(seg.v0[:2]))
            t_stop = seg.t0 + speed / ph.rolling_deceleration
            if seg.kind == "ground" and speed > 0 and t_stop < min(seg.t1, t_next):
                events.append({"kind": "stop", "t": round(t_stop, 6),
                               "position": [round(float(x), 4) for x in seg.state(t_stop, ph)[0]]})
        # the frames after the kick up to the next kick (that frame still shows the ball before its kick)
        for f in range(kick_frame + 1 if frames else 0, min(nxt, n_frames - 1) + 1):
            t = f / fps
            pos, vel, seg = state_at(segs, t, ph)
            frames.append({"frame": f, "t": round(t, 6), "ball_3d": [float(x) for x in pos],
                           "ball_velocity": [round(float(x), 4) for x in vel],
                           "phase": seg.kind, "motion_piece": int(seg.piece)})
            third_visits[int(np.clip((pos[0] + PITCH_HALF[0]) // 35.0, 0, 2))] += 1
        if nxt >= n_frames:
            break
        pos, _, seg = state_at(segs, nxt / fps, ph)
        p = pos.copy()
        piece = seg.piece + 1
        kick_frame = nxt
    return kicks, events, frames


# ----------------------------------------------------------------------------------------------------
# cameras and labels
# ----------------------------------------------------------------------------------------------------

def sphere_box(cam: Camera, centre: np.ndarray, radius: float, samples: int = 720) -> np.ndarray | None:
    """[x1, y1, x2, y2] (px) of the ball's silhouette: its rim circle (the points where rays from the camera
    graze the sphere) projected with the camera's distortion; ``None`` when the ball is behind the camera."""
    axis = centre - cam.C
    D = float(np.linalg.norm(axis))
    if D <= radius:
        return None
    n = axis / D
    a = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    rho = radius * np.sqrt(1.0 - (radius / D) ** 2)
    mid = cam.C + n * (D - radius * radius / D)
    ang = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    rim = mid + rho * (np.cos(ang)[:, None] * a + np.sin(ang)[:, None] * b)
    uv, ok = cam.project(rim)
    if not ok.all():
        return None
    return np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])


def _occlusion_chain(rng: np.random.Generator, n: int, nm: NoiseModel) -> np.ndarray:
    """(n,) bool: occluded frames of one camera (module docstring: a two-state chain)."""
    start = nm.p_occluded / nm.occlusion_mean_length_frames
    end = 1.0 / nm.occlusion_mean_length_frames
    out = np.zeros(n, bool)
    state = False
    u = rng.random(n)
    for i in range(n):
        state = (u[i] >= end) if state else (u[i] < start)
        out[i] = state
    return out


def label_frames(frames: list[dict], cameras: dict[str, Camera], size: tuple[int, int], rng: np.random.Generator,
                 nm: NoiseModel, ph: Physics) -> None:
    """Add ``cams`` (the dev truth's per-camera keys) to each frame of ``frames``, in place."""
    W, H = size
    n = len(frames)
    occ = {cid: _occlusion_chain(rng, n, nm) for cid in cameras}
    balls = np.array([f["ball_3d"] for f in frames])
    for cid, cam in cameras.items():
        uv, front = cam.project(balls)
        dist = np.linalg.norm(balls - cam.C, axis=1)
        noise = rng.normal(0.0, nm.point_sigma_px, (n, 2))
        u_out = rng.random(n)
        for i, fr in enumerate(frames):
            c = uv[i]
            inside = bool(front[i] and 0.0 <= c[0] < W and 0.0 <= c[1] < H)
            entry = {"in_image": inside, "occluded": bool(inside and occ[cid][i]), "annotated": False,
                     "outlier": False,
                     "center_px": [float(c[0]), float(c[1])] if front[i] else None,
                     "d_true": float(2.0 * cam.K[1, 1] * np.tan(np.arcsin(ph.ball_radius_m / dist[i])))}
            if inside:
                box = sphere_box(cam, balls[i], ph.ball_radius_m)
                entry["precise_box"] = [float(x) for x in box]
                entry["precise_box_exact_center"] = [float(0.5 * (box[0] + box[2])), float(0.5 * (box[1] + box[3]))]
            if inside and not entry["occluded"]:
                entry["annotated"] = True
                if u_out[i] < nm.p_outlier:
                    entry["outlier"] = True
                    while True:
                        q = rng.uniform([0.0, 0.0], [W, H])
                        if np.linalg.norm(q - c) >= nm.outlier_min_distance_px:
                            break
                else:
                    q = c + noise[i]
                entry["annotated_px"] = [round(float(q[0]), 2), round(float(q[1]), 2)]
            fr.setdefault("cams", {})[cid] = entry


# ----------------------------------------------------------------------------------------------------
# summary and files
# ----------------------------------------------------------------------------------------------------

def pitch_coverage(cameras: dict[str, Camera], size: tuple[int, int], grid: tuple[int, int] = (53, 46),
                   margin_m: tuple[float, float] = (0.0, 2.0)) -> dict:
    """Share of the pitch seen by at least one / two cameras, and the number of cameras that see all of it:
    over a ``grid`` of points on the ground (``z = 0``) ``margin_m`` inside the lines. The defaults
    reproduce the dev truth's ``coverage_2`` (0.916735...) exactly with the dev cameras."""
    W, H = size
    xs = np.linspace(-PITCH_HALF[0] + margin_m[0], PITCH_HALF[0] - margin_m[0], grid[0])
    ys = np.linspace(-PITCH_HALF[1] + margin_m[1], PITCH_HALF[1] - margin_m[1], grid[1])
    X, Y = np.meshgrid(xs, ys)
    pts = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)
    seen = []
    for cam in cameras.values():
        uv, ok = cam.project(pts)
        seen.append(ok & (uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H))
    seen = np.array(seen)
    count = seen.sum(0)
    return {"coverage_1": float(np.mean(count >= 1)), "coverage_2": float(np.mean(count >= 2)),
            "cameras_seeing_whole_pitch": int(np.sum(seen.all(1)))}


def summarise(frames: list[dict], kicks: list[dict], events: list[dict], cameras: dict[str, Camera], size,
              fps: float, ph: Physics, seconds: float) -> dict:
    """The dev truth's ``summary`` (module docstring), plus events, phase shares and kicks per second."""
    per = {}
    for cid in cameras:
        c = [f["cams"][cid] for f in frames]
        per[cid] = {"in_image": sum(x["in_image"] for x in c), "annotated": sum(x["annotated"] for x in c),
                    "occluded": sum(x["occluded"] for x in c), "outliers": sum(x["outlier"] for x in c)}
    n = len(frames)
    air = sum(f["phase"] == "air" for f in frames)
    rest = sum(f["phase"] == "ground" and not any(f["ball_velocity"]) for f in frames)
    by_ann: dict[str, int] = {}
    for f in frames:
        k = str(sum(c["annotated"] and not c["outlier"] for c in f["cams"].values()))
        by_ann[k] = by_ann.get(k, 0) + 1
    return {
        "frames": n, "seconds": round(seconds, 1), "per_camera": per,
        **pitch_coverage(cameras, size),
        "kicks": len(kicks), "max_height_m": round(max(-f["ball_3d"][2] for f in frames), 3),
        "video_bytes": None,
        "kicks_per_second": round(len(kicks) / (n / fps), 4),
        "lofted_kicks": sum(k["lofted"] for k in kicks),
        "events": {kind: sum(e["kind"] == kind for e in events) for kind in ("bounce", "roll", "stop", "wall")},
        "phase_share": {"air": air / n, "ground_moving": (n - air - rest) / n, "ground_at_rest": rest / n},
        "frames_by_correct_labels": dict(sorted(by_ann.items(), key=lambda kv: int(kv[0]))),
        "frames_ball_in_no_image": sum(not any(c["in_image"] for c in f["cams"].values()) for f in frames),
    }


def points_csv(frames: list[dict], camera_ids) -> str:
    """``ball_points.csv`` text: ``frame, x_cam1, y_cam1, ...``, a row per frame, empty cells without a label."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["frame"] + [f"{a}_cam{c}" for c in camera_ids for a in ("x", "y")])
    for fr in frames:
        row = [fr["frame"]]
        for cid in camera_ids:
            c = fr["cams"][cid]
            row += [f"{c['annotated_px'][0]:.2f}", f"{c['annotated_px'][1]:.2f}"] if c["annotated"] else ["", ""]
        w.writerow(row)
    return buf.getvalue()


def generate(out_dir: str | Path, *, seconds: float = 60.0, seed: int = 1, truth_path: str | Path | None = None,
             cameras_json: str | Path | None = None, lines_json: str | Path | None = None, fps: float = FPS,
             physics: Physics = Physics(), noise: NoiseModel = NoiseModel(),
             image_size: tuple[int, int] = (1920, 1080)) -> dict:
    """Write an ISSIA folder and its truth (module docstring); returns the truth.

    Args:
        out_dir: the folder (created; its three files overwritten).
        seconds: duration; ``round(seconds * fps)`` frames.
        seed: the random seed (same seed, same arguments: the same files).
        truth_path: where the truth goes (default ``<out_dir>.truth.json``).
        cameras_json, lines_json: ``issia_calibration.json`` and ``issia_lines.json`` to use (default: the
            dev set's); the lines are copied as they are (they must belong to those cameras).
    """
    t_start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cameras_json = Path(cameras_json) if cameras_json else DEV_DIR / "issia_calibration.json"
    lines_json = Path(lines_json) if lines_json else DEV_DIR / "issia_lines.json"
    cam_data = json.loads(cameras_json.read_text())
    cameras = {cid: Camera.from_soccernet(cam_data[cid]) for cid in CAMERA_IDS if cid in cam_data}
    rng = np.random.default_rng(seed)
    n = int(round(seconds * fps))
    kicks, events, frames = simulate(n, fps, rng, physics)
    label_frames(frames, cameras, image_size, rng, noise, physics)
    truth = {
        "generator": "v3d benchmarks/issia_synth.py",
        "seed": seed, "fps": fps, "duration_s": n / fps, "image_size": list(image_size), "video_size": None,
        "frame_numbering": f"frame i is at t = i / {fps:g} s, starting at 0 (same index as ball_points.csv)",
        "conventions": {
            "world": "SoccerNet: metres, origin centre spot, x along length, y along width, z down",
            "image": f"continuous pixels at {image_size[0]}x{image_size[1]}, top-left corner (0,0)",
            "d_true": f"2*fy*tan(asin({physics.ball_radius_m}/D)) (on-axis formula)",
            "precise_box": "exact axis-aligned box of the ball image (rim circle projected); "
                           "centre precise_box_exact_center",
            "center_px": "projection of the ball centre",
        },
        "physics": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(physics).items()},
        "noise_model": asdict(noise),
        "cameras": {cid: cam_data[cid] for cid in cameras},
        "kicks": kicks,
        "events": events,
        "summary": None,
        "frames": frames,
    }
    (out / "issia_calibration.json").write_text(json.dumps(truth["cameras"], indent=1))
    shutil.copyfile(lines_json, out / "issia_lines.json")
    (out / "ball_points.csv").write_text(points_csv(frames, list(cameras)))
    truth["summary"] = summarise(frames, kicks, events, cameras, image_size, fps, physics,
                                 time.perf_counter() - t_start)
    truth_path = Path(truth_path) if truth_path else out.with_name(out.name + ".truth.json")
    truth_path.write_text(json.dumps(truth))
    return truth


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="the ISSIA folder to write")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--truth", type=Path, help="truth JSON (default OUT.truth.json beside the folder)")
    ap.add_argument("--cameras", type=Path, help="issia_calibration.json to use (default: the dev set's)")
    ap.add_argument("--lines", type=Path, help="issia_lines.json to copy (default: the dev set's)")
    args = ap.parse_args(argv)
    truth = generate(args.out, seconds=args.seconds, seed=args.seed, truth_path=args.truth,
                     cameras_json=args.cameras, lines_json=args.lines)
    print(json.dumps(truth["summary"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
