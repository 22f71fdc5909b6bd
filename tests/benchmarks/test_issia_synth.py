"""benchmarks/issia_synth.py: a short generated sequence is a valid ISSIA folder whose truth agrees with its
points and with the physics the generator states (not the method's figures: benchmarks/issia_long.py measures
those)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from app.datasets.issia import read_issia
from app.geometry.camera import Camera
from benchmarks.issia_synth import NoiseModel, Physics, generate

pytestmark = pytest.mark.shared
SECONDS, SEED = 12.0, 11
PH, NM = Physics(), NoiseModel()
DT = 1 / 25.0


@pytest.fixture(scope="module")
def sequence(shared_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("issia-synth") / "seq"
    truth = generate(out, seconds=SECONDS, seed=SEED)
    return out, truth


def test_folder_reads_and_points_are_the_truths_labels(sequence):
    out, truth = sequence
    seq = read_issia(out)
    assert seq.camera_ids == ("1", "2", "3", "4", "5", "6")
    assert seq.frames == tuple(range(int(SECONDS * 25)))
    assert set(seq.cameras) == set(truth["cameras"]) and set(seq.lines) == set(seq.camera_ids)
    assert json.loads(out.with_name("seq.truth.json").read_text())["frames"] == truth["frames"]
    for fr in truth["frames"]:
        for k, cid in enumerate(seq.camera_ids):
            c = fr["cams"][cid]
            p = seq.points[fr["frame"], k]
            if c["annotated"]:
                assert np.allclose(p, c["annotated_px"], atol=0.006)
            else:
                assert np.isnan(p).all()


def test_label_flags_and_positions_agree_with_the_cameras(sequence):
    _, truth = sequence
    cams = {cid: Camera.from_soccernet(c) for cid, c in truth["cameras"].items()}
    normal, flags = [], {"annotated": 0, "outlier": 0, "occluded": 0}
    for fr in truth["frames"]:
        ball = np.array(fr["ball_3d"])
        for cid, c in fr["cams"].items():
            uv = cams[cid].project(ball[None])[0][0]
            assert np.allclose(c["center_px"], uv)
            assert c["in_image"] == bool(0 <= uv[0] < 1920 and 0 <= uv[1] < 1080)
            assert c["annotated"] == (c["in_image"] and not c["occluded"])
            assert not (c["outlier"] and not c["annotated"]) and not (c["occluded"] and not c["in_image"])
            if c["in_image"]:
                box = c["precise_box"]
                assert box[0] < uv[0] < box[2] and box[1] < uv[1] < box[3]
            if c["annotated"]:
                off = np.linalg.norm(np.subtract(c["annotated_px"], uv))
                if c["outlier"]:
                    assert off >= NM.outlier_min_distance_px
                else:
                    normal.append(off)
            for key in flags:
                flags[key] += c[key]
    assert np.max(normal) < 6 * NM.point_sigma_px and 0.5 < np.sqrt(np.mean(np.square(normal)) / 2) < 0.9
    assert flags["annotated"] > 200
    per_camera = truth["summary"]["per_camera"]
    assert sum(v["annotated"] for v in per_camera.values()) == flags["annotated"]
    assert sum(v["outliers"] for v in per_camera.values()) == flags["outlier"]


def test_motion_follows_the_stated_physics(sequence):
    _, truth = sequence
    frames = truth["frames"]
    P = np.array([f["ball_3d"] for f in frames])
    assert np.all(P[:, 2] <= -PH.ball_radius_m + 1e-9)  # never below the grass
    kicks = {k["frame"] for k in truth["kicks"]}
    order = sorted(kicks)
    assert order[0] == 0 and all(b - a >= PH.min_kick_interval_s * 25 - 1e-9
                                 for a, b in zip(order, order[1:], strict=False))
    for k in truth["kicks"]:
        assert -k["position"][2] <= PH.receive_max_height_m + 1e-6
        assert PH.kick_speed_range[0] - 1e-3 <= k["speed"] <= PH.kick_speed_range[1] + 1e-3
    checked = {"air": 0, "ground": 0}
    for i in range(1, len(frames) - 1):
        a, b, c = frames[i - 1], frames[i], frames[i + 1]
        if not a["motion_piece"] == b["motion_piece"] == c["motion_piece"] or b["frame"] in kicks:
            continue
        acc = (P[i + 1] - 2 * P[i] + P[i - 1]) / DT ** 2
        if b["phase"] == "air":
            assert np.allclose(acc, [0.0, 0.0, PH.g], atol=1e-6)
        else:
            assert P[i, 2] == pytest.approx(-PH.ball_radius_m)
            v = np.array(b["ball_velocity"][:2])
            if np.linalg.norm(v) > 0.2 and np.linalg.norm(c["ball_velocity"][:2]) > 0:  # rolling, not stopping
                assert np.allclose(acc[:2], -PH.rolling_deceleration * v / np.linalg.norm(v), atol=1e-3)
        checked[b["phase"]] += 1
    assert checked["air"] > 20 and checked["ground"] > 20


def test_same_seed_same_files(sequence, tmp_path):
    out, _ = sequence
    again = tmp_path / "again"
    generate(again, seconds=SECONDS, seed=SEED)
    assert (again / "ball_points.csv").read_text() == (out / "ball_points.csv").read_text()
    generate(tmp_path / "other", seconds=SECONDS, seed=SEED + 1)
    assert (tmp_path / "other" / "ball_points.csv").read_text() != (out / "ball_points.csv").read_text()
