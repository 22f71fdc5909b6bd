"""benchmarks/scale.py on one game of the scale set (a subset of two) and a few requests, so that the harness cannot
rot: the import is measured (figures agree with the labels), both databases are served and measured, the
nudged ball boxes are restored, and the report compares the two."""
from __future__ import annotations

import importlib.util
import json
import sys
import tarfile
from pathlib import Path

import httpx
import pytest

from app.core.paths import PROJECT_ROOT

pytest.importorskip("psutil", reason="psutil (the bench and test extras) is needed by benchmarks/scale.py")


def _load_scale():
    spec = importlib.util.spec_from_file_location("bench_scale", PROJECT_ROOT / "benchmarks" / "scale.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_scale"] = module
    spec.loader.exec_module(module)
    return module


scale = _load_scale()


@pytest.fixture(scope="module")
def two_games(shared_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The first two games (by path) of soccernet-v3-scale.tar.gz, unpacked (labels only)."""
    archive = shared_dir / "data" / "synthetic" / "soccernet-v3-scale.tar.gz"
    if not archive.is_file():
        pytest.skip(f"{archive} not found: the scale set is unavailable")
    dest = tmp_path_factory.mktemp("scale")
    with tarfile.open(archive) as tar:
        labels = sorted((m for m in tar.getmembers() if m.name.endswith("/Labels-v3.json")), key=lambda m: m.name)
        tar.extractall(dest, members=labels[:2], filter="data")
    root = next(p for p in dest.iterdir() if p.is_dir())
    assert len(scale.game_dirs(root)) == 2
    return root


def test_game_dirs_names_a_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(scale.BenchError, match="no such folder"):
        scale.game_dirs(tmp_path / "absent")
    with pytest.raises(scale.BenchError, match="Labels-v3.json"):
        scale.game_dirs(tmp_path)


def test_harness_on_one_game(two_games: Path, tmp_path: Path) -> None:
    subset = scale.subset_tree(two_games, 1, tmp_path / "one")
    assert [g.name for g in scale.game_dirs(subset)] == [scale.game_dirs(two_games)[0].name]
    labels = [json.loads((g / "Labels-v3.json").read_text()) for g in scale.game_dirs(subset)]

    figures = scale.run_import(subset, tmp_path / "scale.sqlite3", workers=1)
    assert figures.games == 1
    assert figures.systems == sum(len(d["actions"]) for d in labels)
    assert figures.systems < figures.frames <= sum(len(d["actions"]) + len(d["replays"]) for d in labels)
    assert figures.frames_per_s == pytest.approx(figures.frames / figures.seconds)
    assert 50.0 < figures.peak_mb < 4096.0 and figures.peak_processes >= 1  # one Python with numpy at least
    assert "calibrating" in figures.stage_seconds
    # The main process's share of the tree's CPU (the rest is its calibration workers', if any).
    assert 0.0 < figures.main_cpu_ms_per_frame <= figures.cpu_ms_per_frame
    # Shared pages counted once (PSS) never sum above the RSS counting them in each process; the main process's share
    # is part of each sum.
    assert 0.0 < figures.main_pss_mb <= figures.peak_pss_mb <= figures.peak_mb
    assert 0.0 < figures.main_rss_mb <= figures.peak_mb

    with scale.Server(tmp_path / "scale.sqlite3") as server:
        assert httpx.get(f"{server.base_url}/api/systems").status_code == 401  # the benchmark logs in
        before = httpx.get(f"{server.base_url}/api/systems", params={"limit": 500}, headers=server.headers).json()
        measured = scale.measure_server(server.base_url, requests=3, seed=1, headers=server.headers)
        ids = [s["id"] for s in before["items"]]
        boxes_before = {v["frame_id"]: v["ball"]["box"] for i in ids
                        for v in httpx.get(f"{server.base_url}/api/systems/{i}",
                                           headers=server.headers).json()["views"]}
    assert measured["systems"] == figures.systems
    assert 0 < measured["queue_p50_ms"] <= measured["queue_p95_ms"]
    assert measured["queue_depth_p95_ms"] > 0 and any(k.endswith(" offset")
                                                      for k in measured["queue_depth_variant_p95_ms"])
    assert measured["system_p95_ms"] > 0 and measured["export_s"] > 0 and measured["export_mb"] > 0
    assert measured["ball_edits"] >= 2 and measured["ball_edits"] % 2 == 0  # each nudge is undone
    with scale.Server(tmp_path / "scale.sqlite3") as server:
        boxes_after = {v["frame_id"]: v["ball"]["box"] for i in ids
                       for v in httpx.get(f"{server.base_url}/api/systems/{i}", headers=server.headers).json()["views"]}
    assert boxes_after == boxes_before

    demo = {**measured, "queue_p95_ms": measured["queue_p95_ms"] / 2}
    rows = {r["measure"]: r for r in scale.compare(demo, measured)}
    assert rows["queue_p95_ms"]["ratio"] == pytest.approx(2.0)
    report = scale.format_report({"import": figures.__dict__, "demo": demo, "scale": measured})
    assert "frames/s" in report and "queue_p95_ms" in report and "main process" in report


def test_main_names_a_missing_database(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert scale.main(["--skip-import", "--db", str(tmp_path / "none.sqlite3"), "--work-dir", str(tmp_path)]) == 2
    assert "none.sqlite3" in capsys.readouterr().err


def test_with_images_each_game_gets_a_frames_zip_whose_headers_the_import_checks(
        two_games: Path, tmp_path: Path) -> None:
    """``--with-images`` (issue 15: the scale import's frames/s with the image checks on): every action and replay
    image of the labels is a PNG member of the game's Frames-v3.zip, at the labelled size, as the reader finds it."""
    import zipfile

    from app.datasets.files import member_image_header
    from app.datasets.soccernet_v3 import FrameImages

    game = scale.game_dirs(scale.subset_tree(two_games, 1, tmp_path / "img", images=True))[0]
    labels = json.loads((game / "Labels-v3.json").read_text())
    entries = {**labels["actions"], **labels["replays"]}
    with zipfile.ZipFile(game / "Frames-v3.zip") as zf:
        assert sorted(zf.namelist()) == sorted(entries)
        for name, entry in entries.items():
            header = member_image_header(zf, name, name)
            assert (header.type, header.width, header.height) == (
                "png", entry["imageMetadata"]["width"], entry["imageMetadata"]["height"])
    with FrameImages(game) as images:
        assert {images.locate(name)["image_type"] for name in entries} == {"png"}
