"""Datasets as released (issue 19) on the shared dev sets in ONE database: the whole synthetic SoccerNet-v3 dev set
(two games, images in Frames-v3.zip) and a stretch of the ISSIA dev sequence (frames 0-7, six cameras, videos),
imported with ``v3d import`` into a temporary SQLite file, a ball moved and a view's field lines edited.

* ``v3d export soccernet-v3d --all`` holds every field of every imported ``Labels-v3.json`` (the edited ones under
  ``v3d``), no ISSIA row, and reads as SoccerNet-v3's devkit reads a ``Labels-v3.json``;
* ``v3d export yolo|coco --all`` write exactly the files they report, no name twice, ISSIA's cameras 1-2 in
  test; supervision and pycocotools read them back with every box;
* the SoccerNet-v3D export imported into an empty database gives the same games, systems, frames, lines, ball
  labels, player boxes, calibrations and images.
"""
from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest
import sqlalchemy as sa
from typer.testing import CliRunner

import app.cli.datasets  # registers the commands
import app.cli.detectors  # noqa: F401  # registers its commands
from app.cli._root import cli
from app.core.config import Settings
from app.db.models import Frame, SystemKind
from app.db.session import make_engine, make_session_factory
from benchmarks.release_fidelity import devkit_read, leaf_fields, lost_fields
from tests.services.issia_data import write_issia_stretch

pytestmark = pytest.mark.shared
runner = CliRunner()
DEV = ("data", "synthetic", "soccernet-v3-dev")


@pytest.fixture(scope="module")
def one_db(shared_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    from app.services.curation.editing import replace_field_lines, update_ball_label

    tmp = tmp_path_factory.mktemp("release-cli")
    url = f"sqlite:///{tmp / 'one.sqlite3'}"
    res = runner.invoke(cli, ["import", "soccernet-v3", str(shared_dir.joinpath(*DEV)), "--database-url", url,
                              "--workers", "1"])
    assert res.exit_code == 0, res.output
    issia = write_issia_stretch(shared_dir, tmp / "issia-dev", 0, 7)
    res = runner.invoke(cli, ["import", "issia", str(issia), "--database-url", url])
    assert res.exit_code == 0, res.output
    engine = make_engine(url)
    settings = Settings(database_url=url, calibration_workers=1)
    with make_session_factory(engine)() as session:
        frames = session.scalars(sa.select(Frame).order_by(Frame.id)).all()
        moved = next(f for f in frames if f.system.kind is SystemKind.SOCCERNET_V3 and f.ball_label is not None
                     and f.ball_label.box is not None)
        update_ball_label(session, moved.id, box=[v + 2.5 for v in moved.ball_label.box], settings=settings)
        lined = next(f for f in frames if f.system.kind is SystemKind.SOCCERNET_V3 and f is not moved)
        first = next(iter(lined.field_lines.lines))
        replace_field_lines(session, lined.id, {k: ([[[x, y + 0.5] for x, y in v[0]], *v[1:]] if k == first else v)
                                                for k, v in lined.field_lines.lines.items()}, settings=settings)
        session.commit()
        edited = {"ball": (moved.system.game.match, moved.name), "lines": (lined.system.game.match, lined.name)}
    engine.dispose()
    return {"url": url, "tmp": tmp, "edited": edited, "issia": issia}


def _export(one_db: dict, fmt: str) -> tuple[Path, str]:
    out = one_db["tmp"] / fmt
    res = runner.invoke(cli, ["export", fmt, str(out), "--all", "--database-url", one_db["url"]])
    assert res.exit_code == 0, res.output
    return out, res.output


def _labels(shared_dir: Path) -> dict[str, dict]:
    return {p.parent.name: json.loads(p.read_text()) for p in shared_dir.joinpath(*DEV).rglob("Labels-v3.json")}


def test_the_soccernet_v3d_export_loses_nothing_and_holds_no_issia_row(one_db, shared_dir):
    out, _ = _export(one_db, "soccernet-v3d")
    sources = _labels(shared_dir)
    exported = {p.parent.name: json.loads(p.read_text()) for p in out.rglob("Labels-v3D.json")}
    assert set(exported) == set(sources) and len(sources) == 2
    fields = 0
    for match, source in sources.items():
        doc = exported[match]
        # the curated fields hold the edits; the imported ones are under v3d: put them back to compare
        for what, (m, name) in one_db["edited"].items():
            if m != match:
                continue
            section = "actions" if name in doc["actions"] else "replays"
            entry = doc[section][name]
            if what == "ball":
                i = next(i for i, b in enumerate(entry["bboxes"]) if b["class"] == "Ball")
                assert entry["bboxes"][i] != entry["v3d"]["original_ball"]
                entry["bboxes"][i] = entry["v3d"]["original_ball"]
            else:
                assert entry["lines"] != entry["v3d"]["original_lines"]
                entry["lines"] = entry["v3d"]["original_lines"]
        missing, changed = lost_fields(source, doc)
        assert (missing, changed) == ([], []), (match, missing[:5], changed[:5])
        fields += sum(1 for _ in leaf_fields(source))
        boxes = sum(len(item["bboxes"]) for s in ("actions", "replays") for item in source[s].values())
        assert devkit_read(doc) == boxes  # a SoccerNet-v3 reader reads every box
        assert (out / doc["GameMetadata"]["UrlLocal"] / "Frames-v3.zip").is_file()
    assert fields > 15_000  # measured 15,641 fields over the two games
    with (out / "SNv3D.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 105 and {r["match"] for r in rows} == set(sources)  # no ISSIA row


def test_yolo_and_coco_write_what_they_report_and_split_issia_by_camera(one_db, shared_dir):
    sv = pytest.importorskip("supervision")
    coco_api = pytest.importorskip("pycocotools.coco")
    sources = _labels(shared_dir)
    players = sum(1 for d in sources.values() for s in ("actions", "replays") for item in d[s].values()
                  for b in item["bboxes"] if b["class"] != "Ball")
    yolo, said = _export(one_db, "yolo")
    reported = {s: int(n) for s, n in re.findall(r"(train|val|test): (\d+) image", said)}
    counted: dict[str, int] = {}
    issia_cams: dict[str, set[str]] = {"train": set(), "val": set(), "test": set()}
    boxes_read = 0
    for split in ("train", "val", "test"):  # val: drawn from train, per system
        images = sorted(p.stem for p in (yolo / "images" / split).iterdir())
        labels = sorted(p.stem for p in (yolo / "labels" / split).iterdir())
        assert images == labels and len(images) == len(set(images))
        counted[split] = len(images)
        issia_cams[split] = {m.group(1) for s in images if (m := re.search(r"_(cam\d)_\d{6}$", s))}
        if split == "test":  # supervision decodes every image: the test split (ISSIA's cameras 1-2) is enough
            ds = sv.DetectionDataset.from_yolo(str(yolo / "images" / split), str(yolo / "labels" / split),
                                               str(yolo / "data.yaml"))
            assert len(ds) == len(images)
            boxes_read += sum(len(det) for _, _, det in ds)
        else:
            boxes_read += sum(len(p.read_text().splitlines()) for p in (yolo / "labels" / split).iterdir())
    skipped = sum(int(n) for n in re.findall(r"(\d+) (?:view\(s\) without an image|with a point-only ball)", said))
    assert counted == reported and sum(counted.values()) + skipped == 105 + 48  # every view has its own file
    assert counted["test"] > 0 and skipped < 48  # ISSIA views with an optimised box are written
    reported_boxes = sum(int(n) for n in re.findall(r"(\d+) (?:ball|other) box\(es\)", said))
    assert boxes_read == reported_boxes
    assert issia_cams["test"] == {"cam1", "cam2"} and counted["val"] > 0
    assert issia_cams["train"] | issia_cams["val"] == {"cam3", "cam4", "cam5", "cam6"}
    other_yolo = sum(1 for p in (yolo / "labels").rglob("*.txt") for line in p.read_text().splitlines()
                     if not line.startswith("0 "))
    assert other_yolo == players  # the player boxes come from the database, as imported

    coco, said = _export(one_db, "coco")
    reported_coco = {s: int(n) for s, n in re.findall(r"(train|test): (\d+) image", said)}
    assert reported_coco == {"train": reported["train"] + reported["val"], "test": reported["test"]}
    anns = 0
    for split in ("train", "test"):
        api = coco_api.COCO(str(coco / split / "instances.json"))
        names = [im["file_name"] for im in api.dataset["images"]]
        on_disk = sorted(p.name for p in (coco / split).iterdir() if p.name != "instances.json")
        assert len(names) == len(set(names)) == reported_coco[split] and sorted(names) == on_disk
        anns += len(api.getAnnIds())
    assert anns == boxes_read


def test_the_export_imported_into_an_empty_database_gives_the_same_dataset(one_db, tmp_path):
    from app.services.images.serving import frame_image
    from tests.services.transfer.test_exporting import _snapshot

    out, _ = _export(one_db, "soccernet-v3d")
    url = f"sqlite:///{tmp_path / 'back.sqlite3'}"
    res = runner.invoke(cli, ["import", "soccernet-v3d", str(out), "--database-url", url])
    assert res.exit_code == 0, res.output
    engines = [make_engine(one_db["url"]), make_engine(url)]
    try:
        with make_session_factory(engines[0])() as first, make_session_factory(engines[1])() as back:
            before, after = _snapshot(first, (SystemKind.SOCCERNET_V3,)), _snapshot(back)
            assert len(before) == 105 and set(after) == set(before)
            for key in before:
                assert after[key] == before[key], key
            images = {k: b"".join(frame_image(f).chunks()) for f in first.scalars(sa.select(Frame))
                      if f.system.kind is SystemKind.SOCCERNET_V3 for k in [(f.system.game.match, f.name)]}
            assert {(f.system.game.match, f.name): b"".join(frame_image(f).chunks())
                    for f in back.scalars(sa.select(Frame))} == images
    finally:
        for e in engines:
            e.dispose()
