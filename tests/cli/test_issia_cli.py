"""``v3d import issia`` and ``v3d export issia-3d`` end to end (temporary SQLite file, a stretch of the
dev sequence without videos)."""
from __future__ import annotations

import sqlalchemy as sa
from typer.testing import CliRunner

import app.cli.datasets  # noqa: F401  # registers the commands
from app.cli._root import cli
from app.datasets.issia3d import read_issia3d_csv
from app.db.session import make_engine
from tests.services.issia_data import write_issia_stretch

runner = CliRunner()


def test_import_issia_then_export_all(shared_dir, tmp_path):
    url = f"sqlite:///{tmp_path / 'cli.sqlite3'}"
    root = write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 19, videos=False)
    result = runner.invoke(cli, ["import", "issia", str(root), "--from-lines", "--flip", "1,2", "--database-url", url])
    assert result.exit_code == 0, result.output
    assert "1 game(s), 20 system(s), 120 frame(s) (20 new, 0 changed)" in result.output
    refused = runner.invoke(cli, ["import", "issia", str(root), "--from-lines", "--flip", "1,2", "--database-url", url])
    assert refused.exit_code == 2 and "issia/sequences/issia-dev" in refused.output, refused.output
    again = runner.invoke(cli, ["import", "issia", str(root), "--from-lines", "--flip", "1,2", "--database-url", url,
                                "--merge", "keep-newer"])
    assert "(0 new, 0 changed)" in again.output, again.output
    engine = make_engine(url)
    with engine.connect() as conn:
        assert conn.execute(sa.text("SELECT count(*) FROM systems WHERE kind = 'issia'")).scalar() == 20
        assert conn.execute(sa.text("SELECT count(*) FROM frames WHERE media_flipped")).scalar() == 40  # cam1, cam2
        assert conn.execute(sa.text("SELECT count(*) FROM calibrations WHERE source = 'computed'")).scalar() == 120
    engine.dispose()
    out = tmp_path / "out"
    result = runner.invoke(cli, ["export", "issia-3d", str(out), "--database-url", url])
    assert result.exit_code == 0 and "exported 0 frame row(s) of 0 sequence(s)" in result.output, result.output
    result = runner.invoke(cli, ["export", "issia-3d", str(out), "--all", "--database-url", url])
    assert "exported 20 frame row(s) of 1 sequence(s)" in result.output, result.output
    rows = read_issia3d_csv(out / "issia-dev" / "ISSIA-3D.csv")
    assert [r.frame for r in rows] == list(range(20))
    assert (out / "issia-dev" / "split.json").is_file()


def test_import_issia_bad_flip_names_the_field(shared_dir, tmp_path):
    url = f"sqlite:///{tmp_path / 'cli.sqlite3'}"
    root = write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 5, videos=False)
    result = runner.invoke(cli, ["import", "issia", str(root), "--flip", "7", "--database-url", url])
    assert result.exit_code == 2 and "flipped_cameras" in result.output, result.output
    result = runner.invoke(cli, ["import", "issia", str(tmp_path / "nowhere"), "--database-url", url])
    assert result.exit_code == 2 and "not a folder" in result.output
