"""``v3d import ...`` and ``v3d export ...`` end to end on small datasets (temporary SQLite files)."""
from __future__ import annotations

import csv
import re
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa
from typer.testing import CliRunner

import app.cli.datasets  # noqa: F401  (registers the commands)
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

    again = runner.invoke(cli, ["import", "sn-calibration", str(archive), "--width", "960", "--height", "540",
                                "--database-url", url])
    assert again.exit_code == 0 and "(0 new, 0 changed)" in again.output
    assert _count(url, "frames") == 3

    out = tmp_path / "export"
    accepted = runner.invoke(cli, ["export", "soccernet-v3d", str(out), "--database-url", url])
    assert accepted.exit_code == 0 and "exported 0 system(s)" in accepted.output
    everything = runner.invoke(cli, ["export", "soccernet-v3d", str(out), "--all", "--database-url", url])
    assert everything.exit_code == 0 and "exported 3 system(s) of 1 game(s), 3 row(s)" in everything.output
    with (out / "SNv3D.csv").open() as fh:
        assert [r["main_action"] for r in csv.DictReader(fh)] == ["1.json", "2.json", "3.json"]
    assert (out / "sn-calibration" / "wc" / "annotations" / "Labels-v3D.json").is_file()


def test_import_soccernet_v3_and_v3d(shared_dir, tmp_path, url):
    write_v3_game(shared_dir, tmp_path / "v3", actions=("2.png",))
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 0, result.output
    assert "1 game(s), 1 system(s), 4 frame(s) (1 new, 0 changed)" in result.output
    outcome = re.search(r"calibrated (\d+) .*, refused (\d+); triangulated (\d+) system", result.output).groups()
    assert runner.invoke(cli, ["export", "soccernet-v3d", str(tmp_path / "out"), "--all", "--database-url", url]).exit_code == 0
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
    assert "error:" in result.output and "evil.zip" in result.output and "'../../escape.json'" in result.output
    assert _count(url, "games") == 0

    game_dir = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",))
    (game_dir / "Labels-v3.json").write_text('{"actions": {"0.png": {"imageMetadata": ')
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 2 and "Labels-v3.json: invalid or truncated JSON" in result.output
    assert _count(url, "games") == 0
    with zipfile.ZipFile(archive) as zf:
        assert "../../escape.json" in zf.namelist()  # the archive was read, never extracted
    assert not (tmp_path.parent / "escape.json").exists()

    missing = runner.invoke(cli, ["import", "sn-calibration", str(archive.with_name("absent.zip")), "--database-url", url])
    assert missing.exit_code == 2 and "no such file or folder" in missing.output


@pytest.mark.parametrize("case", ["nan", "outside", "class", "replay", "size"])
def test_each_bad_label_exits_2_naming_file_and_field(shared_dir, tmp_path, url, case):
    from tests.services.test_importing import _damage

    edit, field, detail = _damage(case)
    write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), edit=edit)
    result = runner.invoke(cli, ["import", "soccernet-v3", str(tmp_path / "v3"), "--database-url", url])
    assert result.exit_code == 2
    assert "error:" in result.output and "Labels-v3.json" in result.output
    assert field in result.output and detail in result.output
    assert _count(url, "games") == 0
