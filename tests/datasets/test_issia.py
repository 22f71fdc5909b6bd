"""ISSIA folder reader, frame images, ISSIA-3D.csv both ways, and the issue's figures on ../shared issia-dev."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.core.config import Settings
from app.core.errors import DatasetError
from app.datasets.issia import read_frame_image, read_issia
from app.datasets.issia3d import ISSIA3D_COLUMNS, Issia3DRow, issia3d_rows, read_issia3d_csv, write_issia3d_csv
from app.geometry.calibration import calibrate_frame
from app.geometry.camera import Camera
from app.services.calibration.admission import admission_args
from app.services.issia.cameras import sequence_cameras
from app.services.issia.trajectory import fit_args

#: The admission's gamma and threshold in force (Settings, V3D_ADMIT_JAC_GAMMA and V3D_ADMIT_JAC_MIN), as the import
#: passes them.
ADMIT = admission_args(Settings())
#: The per-frame triangulation's rules of the trajectory fit, the settings' (as the import passes them).
PAIR_RULES = fit_args(Settings())


def _camera(x: float, y: float) -> Camera:
    return Camera.from_parameters(focal_px=2000.0, principal_point=(960.0, 540.0), pan_deg=0.0, tilt_deg=80.0,
                                  roll_deg=0.0, position_m=[x, y, -10.0])


HEADER = "frame," + ",".join(f"x_cam{k},y_cam{k}" for k in range(1, 7))


def make_folder(tmp: Path, csv_text: str | None = None, cameras=(1, 2, 3, 4, 5, 6)) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    cal = {str(k): _camera(-20 + 8 * k, 60 + k).to_soccernet() for k in cameras}
    (tmp / "issia_calibration.json").write_text(json.dumps(cal))
    if csv_text is None:
        csv_text = HEADER + "\n0,,,,,980.5,326.0,1056.9,338.6,,,,\n1,,,,,995.3,327.4,1038.9,336.7,,,12.0,13.0\n"
    (tmp / "ball_points.csv").write_text(csv_text)
    return tmp


def test_reads_folder_into_records(tmp_path):
    seq = read_issia(make_folder(tmp_path))
    assert seq.camera_ids == ("1", "2", "3", "4", "5", "6") and seq.frames == (0, 1)
    assert seq.point(0, "3") == (980.5, 326.0) and seq.point(0, "1") is None and seq.point(1, "6") == (12.0, 13.0)
    assert seq.points.shape == (2, 6, 2)
    assert set(seq.cameras) == set(seq.camera_ids) and seq.lines == {} and seq.media == {}
    assert sequence_cameras(seq, **ADMIT, pair_rules=PAIR_RULES)["4"].source == "calibration_json"


@pytest.mark.parametrize("text, field", [
    ("frame,x_cam1,y_cam1,x_cam2\n0,1,2,3\n", "header"),
    ("frame,x_cam1,y_cam2\n0,1,2\n", "header"),
    (HEADER + "\n0,1.0,,,,,,,,,,,\n", "row 2 x_cam1/y_cam1"),
    (HEADER + "\nzero,,,,,,,,,,,,\n", "row 2 frame"),
    (HEADER + "\n0,a,b,,,,,,,,,,\n", "row 2 cam1"),
    (HEADER + "\n0,,,,,,,,,,,\n", "row 2"),
    (HEADER + "\n3,,,,,,,,,,,,\n2,,,,,,,,,,,,\n", "row 3 frame"),
])
def test_malformed_points_csv_names_file_and_field(tmp_path, text, field):
    with pytest.raises(DatasetError) as exc:
        read_issia(make_folder(tmp_path, text))
    assert exc.value.field == field and "ball_points.csv" in str(exc.value)


@pytest.mark.parametrize("text, message", [
    ("", "empty file"),
    (b"\xff\xfe" + "frame".encode("utf-16-le"), "not a readable CSV"),
    ("\ufeff" + HEADER + "\n0,,,,,980.5,326.0,,,,,,\n", None),  # a BOM is dropped
    (HEADER + "\n" + "0,,,,,,,,,,,,\n" * 200, "larger than 2000 bytes"),
])
def test_points_csv_is_read_within_bounds(tmp_path, monkeypatch, text, message):
    monkeypatch.setattr("app.datasets.issia.MAX_CSV_BYTES", 2000)
    folder = make_folder(tmp_path)
    path = folder / "ball_points.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    if message is None:
        assert read_issia(folder).point(0, "3") == (980.5, 326.0)
        return
    with pytest.raises(DatasetError, match=message) as exc:
        read_issia(folder)
    assert "ball_points.csv" in str(exc.value)


def test_missing_and_unknown_cameras(tmp_path):
    seq = read_issia(make_folder(tmp_path / "a", cameras=(1, 2, 3, 4, 5)))
    choice = sequence_cameras(seq, **ADMIT, pair_rules=PAIR_RULES)
    assert choice["6"].camera is None and "not in issia_calibration.json" in choice["6"].reason
    folder = make_folder(tmp_path / "b")
    cal = json.loads((folder / "issia_calibration.json").read_text())
    cal["7"] = cal["1"]
    (folder / "issia_calibration.json").write_text(json.dumps(cal))
    with pytest.raises(DatasetError) as exc:
        read_issia(folder)
    assert exc.value.field == "7"
    del cal["7"]
    del cal["2"]["rotation_matrix"], cal["2"]["pan_degrees"]
    (folder / "issia_calibration.json").write_text(json.dumps(cal))
    with pytest.raises(DatasetError) as exc:
        read_issia(folder)
    assert exc.value.field == "2"
    with pytest.raises(DatasetError, match="needs issia_calibration.json or issia_lines.json"):
        (folder / "issia_calibration.json").unlink()
        read_issia(folder)
    with pytest.raises(DatasetError) as exc:
        read_issia(make_folder(tmp_path / "c"), flipped_cameras=["9"])
    assert exc.value.field == "flipped_cameras"


def test_frame_images_are_scaled_to_annotation_and_flipped(tmp_path):
    folder = make_folder(tmp_path)
    frames = folder / "frames" / "cam3"
    frames.mkdir(parents=True)
    img = np.zeros((540, 960, 3), np.uint8)
    img[100:110, 10:20] = (0, 0, 255)  # a red mark near the left edge at 960x540
    cv2.imwrite(str(frames / "000001.png"), img)
    seq = read_issia(folder, flipped_cameras=["3"])
    native = read_frame_image(seq, "3", 1, at_annotation_size=False)
    assert native.image.shape == (540, 960, 3) and native.scale == (2.0, 2.0)
    ys, xs = np.nonzero(native.image[:, :, 2] > 128)
    assert xs.min() >= 940  # mirrored footage: the mark comes back on the right
    full = read_frame_image(seq, "3", 1)
    assert full.image.shape == (1080, 1920, 3) and full.scale == (1.0, 1.0)
    ys, xs = np.nonzero(full.image[:, :, 2] > 128)
    assert abs(ys.mean() - 2 * 104.5) < 2 and abs(xs.mean() - (1920 - 2 * 14.5)) < 2
    with pytest.raises(DatasetError, match="cannot be read"):
        read_frame_image(seq, "3", 7)
    with pytest.raises(DatasetError, match="no video or frame folder"):
        read_frame_image(seq, "4", 1)


def test_issia3d_csv_round_trip_is_exact(tmp_path):
    rows = [
        Issia3DRow(0, {1: (None,) * 5, 3: (980.24, 326.09, 0.123456789012345, 10.381402452630107, 0.0123),
                       4: (1056.96, 338.68, 1.5, 10.6, 1e-17)}, 2, (0.1, -0.2, -0.11), (3, 4),
                   (0.1000000000000001, -0.2, -0.11), "triangulated"),
        Issia3DRow(1, {6: (12.0, 13.0, None, None, None)}, 1, None, (), (1.0, 2.0, -3.0), "fitted"),
        Issia3DRow(2, {}, 0, None, (), None, None),
    ]
    out = tmp_path / "ISSIA-3D.csv"
    write_issia3d_csv(out, rows)
    header = out.read_text().splitlines()[0].split(",")
    assert tuple(header) == ISSIA3D_COLUMNS and header[-3:] == ["cam_list", "ball_3D_smoothed", "ball_3D_source"]
    back = read_issia3d_csv(out)
    full = [r.per_camera | {k: (None,) * 5 for k in range(1, 7) if k not in r.per_camera} for r in rows]
    assert [b.per_camera for b in back] == full
    assert [(b.frame, b.num_cameras, b.ball_3d, b.cam_list, b.ball_3d_smoothed, b.ball_3d_source) for b in back] == \
        [(r.frame, r.num_cameras, r.ball_3d, r.cam_list, r.ball_3d_smoothed, r.ball_3d_source) for r in rows]
    write_issia3d_csv(tmp_path / "again.csv", back)
    assert (tmp_path / "again.csv").read_text() == out.read_text()
    broken = out.read_text().replace("triangulated", "guessed")
    (tmp_path / "broken.csv").write_text(broken)
    with pytest.raises(DatasetError) as exc:
        read_issia3d_csv(tmp_path / "broken.csv")
    assert exc.value.field == "row 2 ball_3D_source"


@pytest.fixture(scope="module")
def issia_dev(shared_dir):
    root = shared_dir / "data" / "synthetic" / "issia-dev"
    if not root.is_dir():
        pytest.skip(f"{root} not found")
    return read_issia(root), json.loads((root.parent / "issia-dev.truth.json").read_text())


@pytest.mark.shared
@pytest.mark.parametrize("from_lines", [False, True], ids=["calibration_json", "lines"])
def test_issue_figures_on_issia_dev(issia_dev, from_lines, tmp_path):
    from benchmarks.issia import evaluate

    seq, truth = issia_dev
    fig, fit = evaluate(seq, truth, from_lines=from_lines)
    assert fig["ball_3D_coverage"] >= 0.95 and fig["ball_3D_median_error_m"] <= 0.06
    assert fig["smoothed_coverage"] >= 0.98 and fig["smoothed_median_error_m"] <= 0.045
    assert fig["outlier_labels"] > 0 and fig["outliers_in_cam_list"] == 0
    assert fig["correct_kept_share"] >= 0.97
    if from_lines:  # the bundle adjustment of lines and ball: 0.043 / 0.014 m (0.056 / 0.033 m from the lines alone)
        assert fig["ball_3D_median_error_m"] <= 0.048 and fig["smoothed_median_error_m"] <= 0.02
        choice = sequence_cameras(seq, from_lines=True, **ADMIT, pair_rules=PAIR_RULES)
        assert all(c.bundle_adjusted and c.jac > 0.75 for c in choice.values())
        assert choice["4"].ball_assisted  # refused from its lines, resected from the ball, then adjusted
    # the CSV of the fitted sequence survives a round trip and agrees with the fit
    cams = {c: ch.camera
            for c, ch in sequence_cameras(seq, from_lines=from_lines, **ADMIT, pair_rules=PAIR_RULES).items()}
    rows = issia3d_rows(seq, cams, fit)
    write_issia3d_csv(tmp_path / "ISSIA-3D.csv", rows)
    back = read_issia3d_csv(tmp_path / "ISSIA-3D.csv")
    assert back == rows
    assert all(r.ball_3d is None or len(r.cam_list) >= 2 for r in rows)
    assert all(len(r.cam_list) <= r.num_cameras for r in rows)
    with_ball = [r for r in rows if r.ball_3d is not None]
    errs = [r.per_camera[c][2] for r in with_ball for c in r.cam_list]
    assert np.median(errs) < 2.0  # px: the kept labels agree with their frame's ball
    assert all(r.per_camera[c][3] > 0 for r in with_ball for c in r.cam_list)  # optimised box diameter


@pytest.mark.shared
def test_cameras_from_lines_are_judged_at_the_admissions_gamma(issia_dev):
    """A camera calibrated from its lines is admitted by the admission rule at the gamma it is given (the settings'
    ``admit_jac_gamma``, not a gamma of its own): its JaC is the calibration's at that gamma, a camera below the
    threshold is refused with that gamma in its reason, and a gamma the calibration does not score is an error."""
    seq, _ = issia_dev
    own = {cid: calibrate_frame(seq.lines[cid], *seq.image_size) for cid in seq.camera_ids if cid in seq.lines}
    for gamma in (0.005, 0.02):
        key = f"{gamma:g}"
        choice = sequence_cameras(seq, from_lines=True, admit_jac_gamma=gamma, admit_jac_min=0.0, pair_rules=PAIR_RULES,
                                  ball_assist=False, bundle=False)
        calibrated = {cid for cid, res in own.items() if res.camera is not None}
        assert calibrated and all(choice[cid].jac == own[cid].jac[key] for cid in calibrated)
        refused = sequence_cameras(seq, from_lines=True, admit_jac_gamma=gamma, admit_jac_min=1.0,
                                   pair_rules=PAIR_RULES,
                                   ball_assist=False, bundle=False)
        assert all(refused[cid].refusal == "below_admission" and f"JaC@{100 * gamma:g}% " in refused[cid].reason
                   for cid in calibrated)
    with pytest.raises(ValueError, match="admit_jac_gamma"):  # a gamma the calibration does not score
        sequence_cameras(seq, from_lines=True, admit_jac_gamma=0.001, admit_jac_min=0.0, pair_rules=PAIR_RULES)


@pytest.mark.shared
def test_dev_video_frames_come_at_annotation_scale(issia_dev):
    seq, _ = issia_dev
    assert sorted(seq.media) == list(seq.camera_ids) and seq.media["3"].suffix == ".mp4"
    native = read_frame_image(seq, "3", 100, at_annotation_size=False)
    assert native.image.shape == (540, 960, 3) and native.scale == (2.0, 2.0)  # 960x540 video, 1920x1080 labels
    assert read_frame_image(seq, "3", 100).image.shape == (1080, 1920, 3)


def _released_folder(src: Path, dest: Path, *, frame_column: bool) -> Path:
    """``dest`` with ``src``'s calibration and, in place of ball_points.csv, the labels as the authors' release
    writes them (``ISSIA-3D.csv``: every column of the format, the ``frame`` column only when asked)."""
    import csv

    dest.mkdir(parents=True)
    (dest / "issia_calibration.json").write_text((src / "issia_calibration.json").read_text())
    with (src / "ball_points.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    columns = [c for c in ISSIA3D_COLUMNS if frame_column or c != "frame"]
    with (dest / "ISSIA-3D.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns)
        w.writeheader()
        for r in rows:
            cells = {c: "" for c in columns}
            cells.update({k: v for k, v in r.items() if k in cells})
            cells["num_cameras"] = str(sum(bool(r[f"x_cam{k}"]) for k in range(1, 7)))
            w.writerow(cells)
    return dest


@pytest.mark.parametrize("frame_column", [True, False], ids=["frame_column", "row_order"])
def test_the_released_issia3d_csv_reads_as_ball_points(shared_dir, tmp_path, frame_column):
    """Issue 19: ``v3d import issia`` takes the released ISSIA-3D.csv in place of ball_points.csv (x_camK /
    y_camK columns; a frame column when present, else row order): the same labels as ball_points.csv."""
    src = shared_dir / "data" / "synthetic" / "issia-dev"
    expected = read_issia(src)
    assert expected.frames == tuple(range(len(expected.frames)))  # row order == frame index on this set
    got = read_issia(_released_folder(src, tmp_path / "rel", frame_column=frame_column))
    assert got.camera_ids == expected.camera_ids and got.frames == expected.frames
    np.testing.assert_array_equal(got.points, expected.points)


def test_a_broken_released_issia3d_csv_names_row_and_column(tmp_path):
    folder = make_folder(tmp_path / "bad")
    (folder / "ball_points.csv").unlink()
    (folder / "ISSIA-3D.csv").write_text("frame,x_cam1,y_cam1,ball_3D\n0,10.0,,\n")
    with pytest.raises(DatasetError) as err:
        read_issia(folder)
    assert "ISSIA-3D.csv" in str(err.value) and "row 2 x_cam1/y_cam1" in str(err.value)
    (folder / "ISSIA-3D.csv").write_text("frame,ball_3D\n0,\n")
    with pytest.raises(DatasetError, match="no x_camK column"):
        read_issia(folder)
