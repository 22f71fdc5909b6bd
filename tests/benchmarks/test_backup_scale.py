"""``v3d backup`` and ``v3d restore`` of a database of the scale set: the first games of
``soccernet-v3-scale.tar.gz`` in CI's suite, all 400 (12,800 systems) in the slow tier, imported by the real
``v3d import``; the archive verifies, names every table with its rows, and restored into a fresh SQLite file holds
every row of the source, through v3d's models (the figures of ``benchmarks/BACKUP.md`` come from
``benchmarks/backup.py`` on the full one)."""
from __future__ import annotations

import os
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest
import sqlalchemy as sa

from app.db.models import Base
from app.db.session import make_engine
from app.services.backup.archive import verify_archive
from tests.conftest import sizes

pytestmark = pytest.mark.processes

V3D = str(Path(sys.executable).with_name("v3d"))


def _rows(url: str) -> dict[str, list[tuple]]:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return {t.name: [tuple(r) for r in conn.execute(sa.select(t).order_by(*t.primary_key.columns))]
                    for t in Base.metadata.sorted_tables}
    finally:
        engine.dispose()


@pytest.mark.parametrize("games", sizes(3, 400))
def test_a_scale_database_backs_up_and_restores_every_row(games: int, shared_dir: Path, tmp_path: Path) -> None:
    archive = shared_dir / "data" / "synthetic" / "soccernet-v3-scale.tar.gz"
    if not archive.is_file():
        pytest.skip(f"{archive} not found: the scale set is unavailable")
    with tarfile.open(archive) as tar:
        labels = sorted((m for m in tar.getmembers() if m.name.endswith("/Labels-v3.json")), key=lambda m: m.name)
        tar.extractall(tmp_path / "tree", members=labels[:games], filter="data")
    source = {**os.environ, "V3D_DATABASE_URL": f"sqlite:///{tmp_path / 'source.sqlite3'}",
              "V3D_STORAGE_URL": (tmp_path / "store").as_uri(), "V3D_JOBS_DIR": str(tmp_path / "jobs"),
              "V3D_CALIBRATION_WORKERS": "2"}
    imported = subprocess.run([V3D, "import", "soccernet-v3", str(tmp_path / "tree")], env=source,
                              capture_output=True, text=True, timeout=7200)
    assert imported.returncode == 0, imported.stderr[-2000:]
    backup = tmp_path / "scale.zip"
    made = subprocess.run([V3D, "backup", str(backup)], env=source, capture_output=True, text=True, timeout=3600)
    assert made.returncode == 0, made.stderr[-2000:]
    manifest = verify_archive(backup)
    rows = _rows(source["V3D_DATABASE_URL"])
    assert {t.name: t.rows for t in manifest.tables if t.name in rows} == {n: len(r) for n, r in rows.items()}
    assert len(rows["systems"]) == 32 * games  # each game of the scale set holds 32 systems
    target = {**source, "V3D_DATABASE_URL": f"sqlite:///{tmp_path / 'target.sqlite3'}",
              "V3D_STORAGE_URL": (tmp_path / "store-2").as_uri(), "V3D_JOBS_DIR": str(tmp_path / "jobs-2")}
    restored = subprocess.run([V3D, "restore", str(backup)], env=target, capture_output=True, text=True,
                              timeout=3600)
    assert restored.returncode == 0, restored.stderr[-2000:]
    assert _rows(target["V3D_DATABASE_URL"]) == rows
