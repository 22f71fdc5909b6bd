"""``v3d import ...`` and ``v3d export ...`` end to end on small datasets (temporary SQLite files)."""
from __future__ import annotations

import re
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa
from typer.testing import CliRunner

import app.cli.datasets  # noqa: F401  # registers the commands
from app.cli._root import cli
from app.db.session import make_engine
from tests.services.datasets import write_calibration_zip, write_v3_game

runner = CliRunner()


def _count(url: str, table: str) -> int:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return conn.execute(sa.text(f"SELECT count(*) FROM {table}")).scalar()
    finally:
        engine.dispose()


@pytest.fixture
def url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'cli.sqlite3'}"


def test_import_sn_calibration_then_export_all(shared_dir, tmp_path, url):
    archive = write_calibration_zip(shared_dir, tmp_path / "wc" / "annotations.zip")
    result = runner.invoke(cli, ["import", "sn-calibration", str(archive), "--width", "960", "--height", "540",
                                 "--database-url", url, "--workers", "1"])
    assert result.exit_code == 0, result.output
    assert "1 game(s), 3 system(s), 3 frame(s) (3 new, 0 changed)" in result.output
    assert _count(url, "calibrations") == 3

    # its game is stored now: an import of it again says how to merge it, else exits 2 naming the game
    refused = runner.invoke(cli, ["import", "sn-calibration", str(archive), "--width", "960", "--height", "540",
                                  "--database-url", url])
    assert refused.exit_code == 2 and "sn-calibration/wc/annotations" in refused.output, refused.output
    assert "--merge" in runner.invoke(cli, ["import", "sn-calibration", "--help"]).output
    again = runner.invoke(cli, ["import", "sn-calibration", str(archive), "--width", "960", "--height", "540",
                                "--database-url", url, "--merge", "keep-newer"])
    assert again.exit_code == 0 and "(0 new, 0 changed)" in again.output
    assert _count(url, "frames") == 3

    # issue 19: single-view frames leave as cameras (SoccerNet-calibration JSON), not in the SoccerNet-v3D export
    out = tmp_path / "export"
    everything = runner.invoke(cli, ["export", "soccernet-v3d", str(out), "--all", "--database-url", url])
    assert everything.exit_code == 0 and "exported 0 system(s) of 0 game(s), 0 row(s)" in everything.output
    cams = tmp_path / "cameras"
    accepted = runner.invoke(cli, ["export", "cameras", str(cams), "--database-url", url])
    assert accepted.exit_code == 0 and "exported 0 camera(s)" in accepted.output, accepted.output
    admitted = _count(url, "calibrations WHERE admitted AND camera IS NOT NULL")
    assert admitted >= 1
    every = runner.invoke(cli, ["export", "cameras", str(cams), "--all", "--database-url", url])
    assert every.exit_code == 0 and f"exported {admitted} camera(s)" in every.output, every.output
    # issue 28: one predictions zip per image size, names unique across games (<game stem>_<frame stem>)
    with zipfile.ZipFile(cams / "960x540" / "predictions.zip") as zf:
        files = sorted(zf.namelist())
    assert len(files) == admitted and all(re.fullmatch(r"camera_annotations-[0-9a-f]{8}_[123]\.json", f) for f in files)


def test_import_soccernet_v3_and_v3d(shared_dir, tmp_path, url):
    write_v3_game(shared_dir, tmp_path / "v3", actions=("2.png",))
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 0, result.output
    assert "1 game(s), 1 system(s), 4 frame(s) (1 new, 0 changed)" in result.output
    outcome = re.search(r"calibrated (\d+) .*, refused (\d+); triangulated (\d+) system", result.output).groups()
    exported = runner.invoke(cli, ["export", "soccernet-v3d", str(tmp_path / "out"), "--all", "--database-url", url])
    assert exported.exit_code == 0 and "4 row(s) and 4 image(s)" in exported.output
    assert len(list((tmp_path / "out").rglob("Frames-v3.zip"))) == 1
    bare = runner.invoke(cli, ["export", "soccernet-v3d", str(tmp_path / "bare"), "--all", "--no-images",
                               "--database-url", url])
    assert bare.exit_code == 0 and "and 0 image(s)" in bare.output and not list((tmp_path / "bare").rglob("*.zip"))
    other = f"sqlite:///{tmp_path / 'other.sqlite3'}"
    back = runner.invoke(cli, ["import", "soccernet-v3d", str(tmp_path / "out"), "--database-url", other])
    assert back.exit_code == 0, back.output
    # the imported cameras give the same outcome (and are not recomputed)
    assert re.search(r"calibrated (\d+) .*, refused (\d+); triangulated (\d+) system", back.output).groups() == outcome


def test_bad_input_exits_2_with_the_file_and_field_and_stores_nothing(shared_dir, tmp_path, url):
    archive = write_calibration_zip(shared_dir, tmp_path / "evil.zip", extra={"../../escape.json": b"{}"})
    result = runner.invoke(cli, ["import", "sn-calibration", str(archive), "--width", "960", "--height", "540",
                                 "--database-url", url])
    assert result.exit_code == 2
    assert "Error:" in result.output and "evil.zip" in result.output and "'../../escape.json'" in result.output
    assert _count(url, "games") == 0

    game_dir = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",))
    (game_dir / "Labels-v3.json").write_text('{"actions": {"0.png": {"imageMetadata": ')
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 2 and "Labels-v3.json: invalid or truncated JSON" in result.output
    assert _count(url, "games") == 0
    with zipfile.ZipFile(archive) as zf:
        assert "../../escape.json" in zf.namelist()  # the archive was read, never extracted
    assert not (tmp_path.parent / "escape.json").exists()

    missing = runner.invoke(cli, ["import", "sn-calibration", str(archive.with_name("absent.zip")), "--database-url",
                                  url])
    assert missing.exit_code == 2 and "no such file or folder" in missing.output


@pytest.mark.parametrize("case", ["class", "replay", "size"])
def test_each_bad_label_exits_2_naming_file_and_field(shared_dir, tmp_path, url, case):
    from tests.services.transfer.test_importing import _damage

    edit, field, detail = _damage(case)
    write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), edit=edit)
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 2
    assert "Error:" in result.output and "Labels-v3.json" in result.output
    assert field in result.output and detail in result.output
    assert _count(url, "games") == 0


@pytest.mark.parametrize("case", ["nan", "outside", "implausible"])
def test_a_refused_ball_box_leaves_its_game_out_and_says_so(shared_dir, tmp_path, url, case):
    """A ball box the shared label check refuses leaves its game out of the import (the other games import): the
    command says which game, file, entry and why."""
    from tests.services.transfer.test_importing import _damage

    edit, field, detail = _damage(case)
    write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), edit=edit)
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 0, result.output
    left_out = [line for line in result.output.splitlines() if "game left out:" in line]
    assert len(left_out) == 1 and "Labels-v3.json" in left_out[0] and field in left_out[0] and detail in left_out[0]
    assert _count(url, "games") == 0


def test_a_link_leading_out_of_the_dataset_exits_2_naming_it(shared_dir, tmp_path, url):
    """Issue 15, item 1: the ``v3d import`` command is not confined to a data root, but a dataset still
    reads nothing outside its own folder: a frame linked to /etc/passwd exits 2 and stores nothing."""
    game_dir = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), with_images=False)
    (game_dir / "Frames-v3").mkdir()
    (game_dir / "Frames-v3" / "0.png").symlink_to("/etc/passwd")
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 2, result.output
    assert "Frames-v3/0.png: image of frame '0.png': resolves outside the dataset's folder" in result.output
    assert _count(url, "games") == 0


def test_import_split_makes_the_listed_images_the_exports_split(shared_dir, tmp_path, url):
    """Issue 19: ``v3d import split FILE --set train|test`` (lines ``<league>/<season>/<match>/<image>``, as the
    released SNv3D-train.txt / SNv3D-test.txt) sets the split the exports use; unknown lines are reported."""
    import csv

    from app.services.kinds import split_of
    from tests.services.datasets import DEV_GAME

    write_v3_game(shared_dir, tmp_path / "v3", actions=("2.png",))
    assert runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url]).exit_code == 0
    own = split_of("/".join(DEV_GAME))
    other = "test" if own == "train" else "train"
    listed = tmp_path / f"SNv3D-{other}.txt"
    game = "/".join(DEV_GAME)
    listed.write_text(f"{game}/2.png\n{game}/2_1\n\n{game}/99.png\nnowhere/x/y/1.png\nnot-an-image-line\n")
    result = runner.invoke(cli, ["import", "split", str(listed), "--set", other, "--database-url", url])
    assert result.exit_code == 0, result.output
    assert f"2 image(s) of 5 line(s) are now in {other} (2 changed); 3 line(s) name no stored image" in result.output
    for line in (f"{game}/99.png", "nowhere/x/y/1.png", "not-an-image-line"):
        assert f"unknown: {line}" in result.output
    out = tmp_path / "out"
    assert runner.invoke(cli, ["export", "soccernet-v3d", str(out), "--all", "--no-images",
                               "--database-url", url]).exit_code == 0
    with (out / "SNv3D.csv").open() as fh:
        sets = {(r["replay"] or r["main_action"]): r["set"] for r in csv.DictReader(fh)}
    assert sets == {"2.png": other, "2_1.png": other, "2_2.png": own, "2_3.png": own}
    again = runner.invoke(cli, ["import", "split", str(listed), "--set", other, "--database-url", url])
    assert "(0 changed)" in again.output
    bad = runner.invoke(cli, ["import", "split", str(listed), "--set", "val", "--database-url", url])
    assert bad.exit_code == 2 and "set" in bad.output
    missing = runner.invoke(cli, ["import", "split", str(tmp_path / "none.txt"), "--set", "test", "--database-url",
                                  url])
    assert missing.exit_code == 2 and "none.txt" in missing.output
