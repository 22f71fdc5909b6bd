"""Issue 28 item 9: every export as a job with a download, right as downloaded.

* ``POST /api/exports/{format}`` queues each export; its file is served at ``/api/jobs/{id}/result`` to admins
  only, removed after ``V3D_EXPORT_KEEP_HOURS``;
* no file of any export (nested zips included) names the data root, the jobs folder or a /tmp path;
* a YOLO zip (the ``GET`` and the job's), unpacked in one folder and resolved from another working directory the
  way Ultralytics' ``check_det_dataset`` resolves ``data.yaml`` (``ultralytics/data/utils.py``, reimplemented
  below: ultralytics is not installed), finds every image and its label; supervision reads it too.
"""
from __future__ import annotations

import glob
import io
import os
import zipfile
from pathlib import Path

import pytest
import supervision as sv
import yaml
from fastapi.testclient import TestClient

from app.services.exports.files import EXPORT_FORMATS, prune_exports
from tests.services.datasets import zip_files

from ..conftest import run_queued
from ..factories import Scene

#: ``ultralytics.data.utils.IMG_FORMATS`` (the suffixes its datasets take as images).
IMG_FORMATS = {"bmp", "dng", "jpeg", "jpg", "mpo", "png", "tif", "tiff", "webp", "pfm", "heic"}


@pytest.fixture
def jobs_app(app, tmp_path: Path):
    """The app with its export files under this test's folder."""
    app.state.settings = app.state.settings.model_copy(update={"jobs_dir": tmp_path / "jobs"})
    return app


def ultralytics_check_det_dataset(dataset: str, datasets_dir: Path) -> dict:
    """What ``ultralytics.data.utils.check_det_dataset`` does with a local ``data.yaml`` (no download): the YAML
    read with ``yaml_file`` = the path as given; ``train`` and ``val`` required; the root ``path`` key, else the
    YAML's folder, else (relative and missing) under ``datasets_dir``; each split ``(root / value).resolve()`` (a
    missing ``../x`` retried as ``x``); every ``val`` folder must exist, else FileNotFoundError."""
    file = Path(dataset)
    if not file.exists():
        raise FileNotFoundError(dataset)  # check_file: a local file is taken as it is named
    data = yaml.safe_load(file.read_text())
    data["yaml_file"] = str(dataset)
    for k in ("train", "val"):
        if k not in data:
            raise SyntaxError(f"{dataset} '{k}:' key missing")
    path = Path(data.get("path") or Path(data.get("yaml_file", "")).parent)
    if not path.exists() and not path.is_absolute():
        path = (datasets_dir / path).resolve()
    data["path"] = path
    for k in ("train", "val", "test", "minival"):
        if data.get(k):
            if isinstance(data[k], str):
                x = (path / data[k]).resolve()
                if not x.exists() and data[k].startswith("../"):
                    x = (path / data[k][3:]).resolve()
                data[k] = str(x)
            else:
                data[k] = [str((path / x).resolve()) for x in data[k]]
    val = data.get("val")
    if val:
        val = [Path(x).resolve() for x in (val if isinstance(val, list) else [val])]
        if not all(x.exists() for x in val):
            raise FileNotFoundError(f"images not found, missing path '{next(x for x in val if not x.exists())}'")
    return data


def ultralytics_images_and_labels(split_dir: str) -> list[tuple[Path, Path]]:
    """``YOLODataset.get_img_files`` (``glob(p/**/*.*)`` filtered by suffix) and ``img2label_paths`` (the last
    ``/images/`` becomes ``/labels/``, the suffix ``.txt``) of one split folder."""
    files = sorted(f for f in glob.glob(str(Path(split_dir) / "**" / "*.*"), recursive=True)
                   if f.rsplit(".", 1)[-1].lower() in IMG_FORMATS)
    sa, sb = f"{os.sep}images{os.sep}", f"{os.sep}labels{os.sep}"
    return [(Path(x), Path(sb.join(x.rsplit(sa, 1)).rsplit(".", 1)[0] + ".txt")) for x in files]


def _export_job(client: TestClient, app, fmt: str, **body) -> tuple[dict, bytes]:
    job = client.post(f"/api/exports/{fmt}", json={"all": True, **body})
    assert job.status_code == 202, job.text
    assert run_queued(app) == [job.json()["id"]]
    done = client.get(job.json()["url"]).json()
    assert done["state"] == "done", done["message"]
    file = client.get(done["result_url"])
    assert file.status_code == 200 and file.headers["content-type"] == "application/zip"
    return done, file.content



def test_every_export_is_a_job_whose_zip_names_no_server_folder(jobs_app, client: TestClient, scene: Scene,
                                                               tmp_path: Path, act_as) -> None:
    settings = jobs_app.state.settings
    forbidden = {str(tmp_path), str(settings.data_root), str((tmp_path / "jobs").resolve()), "/tmp/"}
    expected = {"soccernet-v3d": "SNv3D.csv", "issia-3d": None, "cameras": "cameras.json", "yolo": "data.yaml",
                "coco": None}
    for fmt in EXPORT_FORMATS:
        if fmt == "issia-3d":  # the scene holds no ISSIA sequence: a job that says so, and no empty zip
            job = client.post(f"/api/exports/{fmt}", json={"all": True})
            assert job.status_code == 202 and run_queued(jobs_app) == [job.json()["id"]]
            done = client.get(job.json()["url"]).json()
            assert done["state"] == "done" and done["result_url"] is None, done
            assert "nothing to export: no ISSIA sequence is stored" in str(done["result"]), done
            assert client.get(f"{job.json()['url']}/result").status_code == 409
            continue
        job, content = _export_job(client, jobs_app, fmt)
        assert job["params"]["format"] == fmt and job["result"]["format"] == fmt
        assert all(k not in job["result"] for k in ("out_dir", "path")) and "/" not in job["result"]["file"]
        files = zip_files(content)
        if expected[fmt]:
            assert expected[fmt] in files, (fmt, sorted(files))
        for name, raw in files.items():
            if name.endswith((".png", ".jpg")):
                continue
            for folder in forbidden:
                assert folder.encode() not in raw, f"{fmt}: {name} names {folder}"
    coco = zip_files(_export_job(client, jobs_app, "coco")[1])
    assert sum(n.endswith("instances.json") for n in coco) == 2 and sum(n.endswith(".png") for n in coco) == 2
    cams = zip_files(_export_job(client, jobs_app, "cameras")[1])
    assert {n.split("!")[0] for n in cams if "!" in n} == {"960x540/ground_truth.zip", "960x540/predictions.zip"}
    names = sorted(n.split("!camera_")[1] for n in cams if "!camera_" in n)
    assert len(names) == 3 and names == sorted(n.split("!train/")[-1].split("!test/")[-1]
                                               for n in cams if "ground_truth.zip!" in n)

    # only the roles that may export see a file; an expired file is gone
    act_as("rita", "reviewer")
    assert client.post("/api/exports/yolo", json={}).status_code == 403
    assert client.get(job["result_url"]).status_code == 403
    act_as("ada", "admin")
    assert client.get(job["result_url"]).status_code == 200
    exports = tmp_path / "jobs" / "exports"
    assert prune_exports(exports, 1.0, now=lambda: 10 ** 12) and not any(exports.iterdir())
    assert client.get(job["result_url"]).status_code == 404
    assert client.post("/api/exports/nope", json={}).status_code == 422
    assert client.post("/api/exports/yolo", json={"all": True, "images": False}).status_code == 422


def _unpack(content: bytes, dest: Path) -> Path:
    with zipfile.ZipFile(io.BytesIO(content)) as zf:
        zf.extractall(dest)
    return dest


@pytest.mark.parametrize("source", ["get", "job"])
def test_a_downloaded_yolo_zip_resolves_as_ultralytics_resolves_it(jobs_app, client: TestClient, scene: Scene,
                                                                  tmp_path: Path, monkeypatch, source: str) -> None:
    if source == "get":
        content = client.get("/api/exports/yolo", params={"all": "true"}).content
    else:
        job, content = _export_job(client, jobs_app, "yolo")
        assert job["result"]["empty_splits"] == [s for s in ("train", "val", "test") if not job["result"]["images"][s]]
    root = _unpack(content, tmp_path / "elsewhere" / "unpacked")
    text = (root / "data.yaml").read_text()
    assert "path:" not in text.replace("# no 'path:' key", "")
    elsewhere = tmp_path / "third" / "cwd"
    elsewhere.mkdir(parents=True)
    monkeypatch.chdir(elsewhere)
    for given in ("../../elsewhere/unpacked/data.yaml", str(root / "data.yaml")):
        data = ultralytics_check_det_dataset(given, tmp_path / "datasets")
        assert Path(data["path"]).resolve() == root.resolve()
        pairs = [p for k in ("train", "val", "test") for p in ultralytics_images_and_labels(data[k])]
        assert Path(data["train"]) == root.resolve() / "images" / "train" and Path(data["train"]).is_dir()
        assert Path(data["val"]) == root.resolve() / "images" / "val" and Path(data["val"]).is_dir()
        images = sorted(p.relative_to(root).as_posix() for p in root.glob("images/*/*.png"))
        assert len(images) == 2 and sorted(img.relative_to(root.resolve()).as_posix() for img, _ in pairs) == images
        assert all(label.is_file() for _, label in pairs)
        balls = [line for _, label in pairs for line in label.read_text().splitlines() if line.startswith("0 ")]
        assert len(balls) == 2
    for split in ("train", "val", "test"):
        empty = not any((root / "images" / split).iterdir())
        assert (f"# split '{split}' has no image" in text) == empty and (root / "labels" / split).is_dir()
        if not empty:
            ds = sv.DetectionDataset.from_yolo(f"../../elsewhere/unpacked/images/{split}",
                                               f"../../elsewhere/unpacked/labels/{split}",
                                               "../../elsewhere/unpacked/data.yaml")
            assert len(ds) == len(list((root / "images" / split).iterdir()))
            assert ds.classes[0] == "Ball" and sum(int((d.class_id == 0).sum()) for _, _, d in ds) >= 1


def test_the_cameras_export_in_the_request(client: TestClient, scene: Scene, act_as) -> None:
    """``GET /api/exports/cameras``: the same zip as ``v3d export cameras`` (per image size the evaluator's pair of
    zips and the index), accepted systems unless ``all``; admins only."""
    every = client.get("/api/exports/cameras", params={"all": "true"})
    assert every.status_code == 200 and every.headers["x-v3d-cameras"] == "3"
    files = zip_files(every.content)
    assert "cameras.json" in files and sum("predictions.zip!camera_" in n for n in files) == 3
    assert sum(n.startswith("960x540/ground_truth.zip!") and n.count("/") == 2 for n in files) == 3
    accepted = client.get("/api/exports/cameras")
    assert accepted.headers["x-v3d-cameras"] == "0" and "cameras.json" in zip_files(accepted.content)
    act_as("rita", "reviewer")
    assert client.get("/api/exports/cameras").status_code == 403
