"""The built-in demo dataset: one synthetic SoccerNet-v3 game made entirely in code.

:func:`generate_demo_dataset` writes::

    <out_dir>/
      demo-truth.json                                   true cameras, balls, boxes, planted problems
      v3d-demo/2024-2025/<game>/Labels-v3.json          SoccerNet-v3 labels (method.md section 9)
      v3d-demo/2024-2025/<game>/Frames-v3.zip           N.png (actions) and N_M.png (replays)

Nine multi-view systems, each an action frame of the main camera with one to three replays
(960x540 PNGs; the first action is 1920x1080). Four replays carry deliberate problems a reviewer
should catch (see :data:`app.demo.scene.PROBLEM_KINDS`): a ball box on the wrong spot, mirrored
field-line labels, a viewpoint less than a metre from the main camera, and a view that sees the ball
without a ball label.

The output is a pure function of ``seed``: the same bytes every time (PNG compression level fixed,
zip entries stored with a fixed timestamp and order, JSON written in a fixed order).

World frame: SoccerNet (metres, origin at the centre spot, z down). Pixels: continuous, origin at
the top-left corner, principal point at ``(W / 2, H / 2)``, no distortion.
"""
from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from app.demo.labels import (
    BALL_BOX_NOISE,
    LINE_SIGMA_PX_AT_1920,
    annotate_field_lines,
    box_iou,
    box_size_error,
    jitter_box,
    loose_ball_box,
    misplaced_ball_box,
    polyline_length,
    visible_runs,
)
from app.demo.render import person_box, render_frame
from app.demo.rig import NEAR_DUPLICATE_OFFSET_M, RIG, framing_camera
from app.demo.scene import (
    BALL_RADIUS_M,
    PROBLEM_KINDS,
    SYSTEMS,
    Person,
    SystemSpec,
    precise_ball_box,
    sample_people,
)
from app.geometry.camera import Camera
from app.geometry.pitch import GOAL_CLASSES, MIRROR_CLASSES, MODEL_CLASSES, sample_pitch_polylines

LEAGUE = "v3d-demo"
SEASON = "2024-2025"
MATCH = "2025-03-15 - 15-00 Northbridge 2 - 1 Easthaven"
TRUTH_FILE = "demo-truth.json"
LABELS_FILE = "Labels-v3.json"
FRAMES_FILE = "Frames-v3.zip"
#: Timestamp of every zip entry (fixed, so that the archive is byte-identical run to run).
ZIP_DATE_TIME = (2025, 3, 15, 15, 0, 0)
PNG_PARAMS = [cv2.IMWRITE_PNG_COMPRESSION, 6]

#: A view is framed wider (zoom out by 15 % steps) until it shows at least this many model
#: classes, straight lines in both pitch directions (or a circle), each visible over
#: ``_RICH_MIN_PX_AT_960`` px: enough for a line-based calibration.
_RICH_MIN_CLASSES = 5
_RICH_MIN_PX_AT_960 = 40.0
_OUTFIELD_PLAYERS = 8


@dataclass
class _View:
    image: str
    role: str
    rig: str
    camera: Camera
    width: int
    height: int
    framing_m: float
    problem: str | None = None
    labels: dict[str, Any] = field(default_factory=dict)
    truth: dict[str, Any] = field(default_factory=dict)


def _line_richness(camera: Camera, width: int, height: int) -> tuple[int, bool]:
    """(number of visible model classes, whether both pitch directions are constrained)."""
    model = sample_pitch_polylines(0.5, 0.5)
    min_len = _RICH_MIN_PX_AT_960 * width / 960.0
    seen: set[str] = set()
    for cls in MODEL_CLASSES:
        uv, ok = camera.project(model[cls])
        if any(polyline_length(r) >= min_len for r in visible_runs(uv, ok, width - 1.0, height - 1.0)):
            seen.add(cls)
    along_x = any(c for c in seen if c in ("Side line top", "Side line bottom") or c.endswith(("top", "bottom")))
    along_y = any(c for c in seen if c.endswith("main") or c in ("Side line left", "Side line right", "Middle line"))
    circle = any(c.startswith("Circle") for c in seen)
    return len(seen), (along_x and along_y) or (circle and (along_x or along_y))


def _aimed_camera(position: np.ndarray, ball: np.ndarray, ball_px: tuple[float, float], framing: float,
                  width: int, height: int, roll_deg: float) -> Camera:
    """Camera at ``position`` framing ``framing`` metres at the ball, turned so that the ball's
    centre lands on pixel ``ball_px`` (a few fixed-point steps on the aimed point)."""
    dist = float(np.linalg.norm(ball - position))
    target = ball.copy()
    for _ in range(8):
        cam = framing_camera(position, target, framing, width, height, roll_deg)
        uv = cam.project(ball[None, :])[0][0]
        err = (uv - np.asarray(ball_px)) * dist / cam.K[0, 0]  # metres at the ball's distance
        # The ball sits right of (below) where it should: turn the axis right (down), i.e. move
        # the aimed point along the camera's x (y) axis expressed in the world.
        target = target + err[0] * cam.R[0] + err[1] * cam.R[1]
    return cam


def _view_camera(rng: np.random.Generator, position: np.ndarray, ball: np.ndarray, framing_range: tuple[float, float],
                 width: int, height: int, roll_deg: float) -> tuple[Camera, float]:
    """Frame the ball as an operator does (near the centre, lower in the picture for low cameras so
    that the grass fills it) and zoom out until the view holds enough field lines to calibrate."""
    framing = float(rng.uniform(*framing_range))
    low_camera, high_ball = -position[2] < 4.0, -ball[2] > 3.0
    row = rng.uniform(0.2, 0.32) if (low_camera or high_ball) else rng.uniform(0.38, 0.55)
    ball_px = (width * (0.5 + rng.uniform(-0.12, 0.12)), height * row)
    for _ in range(12):
        cam = _aimed_camera(position, ball, ball_px, framing, width, height, roll_deg)
        count, both = _line_richness(cam, width, height)
        if count >= _RICH_MIN_CLASSES and both:
            break
        framing *= 1.15
    uv, ok = cam.project(ball[None, :])
    if not (ok[0] and 0.1 * width < uv[0, 0] < 0.9 * width and 0.1 * height < uv[0, 1] < 0.9 * height):
        raise RuntimeError(f"demo camera at {position.tolist()} lost the ball: {uv[0].tolist()}")
    return cam, framing


def _occludes_ball(camera: Camera, person: Person, ball: np.ndarray, ball_box: np.ndarray) -> bool:
    box = person_box(camera, person)
    if box is None:
        return False
    depth = camera.points_in_camera(np.array([[person.xy[0], person.xy[1], -0.9], ball]))[:, 2]
    overlap = not (box[2] < ball_box[0] - 3 or box[0] > ball_box[2] + 3 or box[3] < ball_box[1] - 3
                   or box[1] > ball_box[3] + 3)
    return overlap and depth[0] < depth[1] + 1.0


def _people_for(rng: np.random.Generator, ball: np.ndarray, views: list[_View]) -> list[Person]:
    """Players and referee placed so that none hides the ball in any view (a person still in the
    way after 60 moves is left out)."""
    people = sample_people(rng, ball, _OUTFIELD_PLAYERS)
    boxes = [(v.camera, precise_ball_box(v.camera, ball)) for v in views]
    out: list[Person] = []
    for p in people:
        for _ in range(60):
            if not any(_occludes_ball(cam, p, ball, box) for cam, box in boxes):
                out.append(p)
                break
            xy = np.array(p.xy) + rng.normal(0.0, 4.0, 2)
            p = Person(p.role, p.jersey, (float(np.clip(xy[0], -51.5, 51.5)), float(np.clip(xy[1], -33.0, 33.0))))
    return out


def _box_json(box: np.ndarray, cls: str, ident: str | None) -> dict[str, Any]:
    x1, y1, x2, y2 = (int(v) for v in box)
    return {"points": {"x1": x1, "y1": y1, "x2": x2, "y2": y2}, "class": cls, "ID": ident}


def _floats(a: np.ndarray, nd: int = 4) -> list[float]:
    return [round(float(v), nd) for v in np.asarray(a).ravel()]


def _camera_json(camera: Camera) -> dict[str, Any]:
    data = camera.to_soccernet()
    return json.loads(json.dumps(data), parse_float=lambda s: round(float(s), 10))


def _make_views(rng: np.random.Generator, index: int, spec: SystemSpec, ball: np.ndarray) -> list[_View]:
    main = RIG["main"]
    w, h = spec.action_size
    cam, framing = _view_camera(rng, np.array(main.position_m), ball, main.framing_m, w, h, main.roll_deg)
    views = [_View(f"{index}.png", "action", "main", cam, w, h, framing)]
    for k, rep in enumerate(spec.replays, start=1):
        rig = RIG[rep.rig]
        position = np.array(rig.position_m)
        framing_range = rig.framing_m
        if rep.problem == "near_duplicate_viewpoint":
            position = position + np.array(NEAR_DUPLICATE_OFFSET_M)
            framing_range = (main.framing_m[0] * 0.6, main.framing_m[0] * 0.75)
        rw, rh = rep.size
        cam, framing = _view_camera(rng, position, ball, framing_range, rw, rh, rig.roll_deg)
        views.append(_View(f"{index}_{k}.png", "replay", rep.rig, cam, rw, rh, framing, rep.problem))
    return views


def _label_view(rng: np.random.Generator, view: _View, ball: np.ndarray, people: list[Person],
                model: Any) -> None:
    w, h = view.width, view.height
    lines = annotate_field_lines(view.camera, model, w, h, rng)
    if view.problem == "mirrored_lines":
        lines = [(MIRROR_CLASSES[c], p) for c, p in lines]
    precise = precise_ball_box(view.camera, ball)
    centre_px = view.camera.project(ball[None, :])[0][0]
    loose = loose_ball_box(precise, w, h, rng)
    annotated = misplaced_ball_box(loose, w, h, rng, centre_px) if view.problem == "wrong_ball_box" else loose
    # a missing label: the ball is in the image, the annotator did not box it
    bboxes = [] if view.problem == "missing_ball" else [_box_json(annotated, "Ball", None)]
    for p in people:
        box = person_box(view.camera, p)
        if box is None:
            continue
        jb = jitter_box(box, w, h, rng)
        if jb is not None:
            bboxes.append(_box_json(jb, p.role, p.jersey))
    view.labels = {
        "imageMetadata": {"width": w, "height": h, "imageType": view.role},
        "bboxes": bboxes,
        "lines": [{"class": c, "points": [round(float(v), 2) for v in p.ravel()]} for c, p in lines],
    }
    dist = float(np.linalg.norm(view.camera.C - ball))
    view.truth = {
        "image": view.image, "role": view.role, "rig_camera": view.rig,
        "offset_from_rig_m": _floats(view.camera.C - np.array(RIG[view.rig].position_m), 6),
        "width": w, "height": h,
        "camera": _camera_json(view.camera), "framing_m": round(view.framing_m, 3),
        "distance_to_ball_m": round(dist, 3),
        "ball_center_px": _floats(centre_px), "precise_box": _floats(precise),
        "annotated_box": None if view.problem == "missing_ball" else _floats(annotated),
        "loose_box_before_problem": _floats(loose),
        "box_iou": round(box_iou(loose, precise), 4), "box_size_error": round(box_size_error(loose, precise), 4),
        "line_classes": sorted({c for c, _ in lines}), "problem": view.problem,
    }


def _png(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", img, PNG_PARAMS)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def _write_zip(path: Path, files: list[tuple[str, bytes]]) -> None:
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED) as zf:
        for name, data in files:
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE_TIME)
            info.external_attr = 0o644 << 16
            info.create_system = 3
            zf.writestr(info, data, compress_type=zipfile.ZIP_STORED)


def generate_demo_dataset(out_dir: Path, seed: int = 0) -> Path:
    """Write the demo SoccerNet-v3 game under ``out_dir`` and return the dataset root to import.

    Args:
        out_dir: folder to write into (created if needed); existing demo files are overwritten.
        seed: the only source of randomness (ball jitter, zoom and aim, players, label noise).

    Returns:
        ``out_dir`` itself: the root holding ``<league>/<season>/<game>/`` and ``demo-truth.json``.
    """
    root = Path(out_dir)
    game_dir = root / LEAGUE / SEASON / MATCH
    game_dir.mkdir(parents=True, exist_ok=True)
    model = sample_pitch_polylines(0.1, 0.1)

    actions: dict[str, Any] = {}
    replays: dict[str, Any] = {}
    images: list[tuple[str, bytes]] = []
    systems_truth: list[dict[str, Any]] = []
    problems: dict[str, list[str]] = {k: [] for k in PROBLEM_KINDS}
    for index, spec in enumerate(SYSTEMS):
        rng = np.random.default_rng([seed, index])
        ball = np.array(spec.ball, float)
        ball[:2] += rng.uniform(-1.5, 1.5, 2)
        views = _make_views(rng, index, spec, ball)
        people = _people_for(rng, ball, views)
        for view in views:
            _label_view(rng, view, ball, people, model)
            images.append((view.image, _png(render_frame(view.camera, view.width, view.height, ball, people))))
            if view.problem:
                problems[view.problem].append(view.image)
        action, reps = views[0], views[1:]
        actions[action.image] = {**action.labels, "linked_replays": [r.image for r in reps]}
        for r in reps:
            replays[r.image] = {**r.labels, "linked_action": action.image}
        systems_truth.append({
            "action": action.image, "replays": [r.image for r in reps], "story": spec.story,
            "ball_3d": _floats(ball, 6), "ball_in_air": bool(ball[2] < -BALL_RADIUS_M - 0.05),
            "problems": [{"kind": v.problem, "image": v.image} for v in views if v.problem],
            "people_3d": [[p.role, p.jersey, round(p.xy[0], 3), round(p.xy[1], 3)] for p in people],
            "views": [v.truth for v in views],
        })

    url = f"{LEAGUE}/{SEASON}/{MATCH}/"
    labels = {
        "GameMetadata": {"UrlLocal": url, "UrlYoutube": "", "list_actions": list(actions),
                         "list_replays": list(replays), "num_actions": len(actions), "num_replays": len(replays)},
        "actions": actions,
        "replays": replays,
    }
    (game_dir / LABELS_FILE).write_text(json.dumps(labels), encoding="utf-8")
    _write_zip(game_dir / FRAMES_FILE, images)

    views_truth = [v for s in systems_truth
                   for v in s["views"] if v["problem"] not in ("wrong_ball_box", "missing_ball")]
    truth = {
        "generator": "app.demo.generate_demo_dataset", "seed": seed,
        "conventions": {
            "world": "SoccerNet: metres, origin at the centre spot, x along the length, y along the width, z down",
            "image": "continuous pixels, origin at the top-left corner, principal point (W/2, H/2), no distortion",
            "camera": "SoccerNet-calibration JSON (method.md section 2), at the image's own resolution",
            "ball_diameter_m": 2 * BALL_RADIUS_M,
            "precise_box": "tight box of the exact sphere silhouette (projection of the tangency circle)",
            "ball_center_px": "projection of the ball centre (not the centre of the precise box off-axis)",
        },
        "noise_model": {"ball_box": dict(BALL_BOX_NOISE), "line_sigma_px_at_1920": LINE_SIGMA_PX_AT_1920},
        "game": {"league": LEAGUE, "season": SEASON, "match": MATCH, "url_local": url},
        "rig": {name: {"description": c.description, "position_meters": list(c.position_m)} for name, c in RIG.items()},
        "problems": problems,
        "summary": {
            "systems": len(systems_truth), "views": len(images),
            "mean_box_iou": round(float(np.mean([v["box_iou"] for v in views_truth])), 4),
            "mean_box_size_error": round(float(np.mean([v["box_size_error"] for v in views_truth])), 4),
            "goal_classes_annotated": sorted({c for v in views_truth for c in v["line_classes"] if c in GOAL_CLASSES}),
        },
        "systems": systems_truth,
    }
    (root / TRUTH_FILE).write_text(json.dumps(truth, indent=1), encoding="utf-8")
    return root
