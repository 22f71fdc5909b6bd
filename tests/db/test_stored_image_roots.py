"""Migration 0037: frames stored before the store name their dataset's folder by its key in the folder store (the jobs
folder) or by its path under the data root; other folders stay as they were. A release made before exports the same
bytes after it (its zip's images included), and the downgrade writes the absolute folders back."""
from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa
from alembic import command
from sqlalchemy.orm import Session

from app.core.config import Settings, get_settings, jobs_dir
from app.db.models import Frame, ReviewDecision, ReviewStatus, System
from app.db.session import alembic_config, make_engine
from app.services.exports.files import write_export_zip
from app.services.releases.content import create_release
from tests.api.factories import make_game, make_system


def _roots(session: Session) -> set[str]:
    session.rollback()  # a new read: what the migration wrote since
    return set(session.scalars(sa.select(Frame.image_root).where(Frame.image_root.is_not(None))))


def _export(session: Session, settings: Settings, out: Path) -> bytes:
    write_export_zip(session, "soccernet-v3d", out, False, settings, release="v1")
    return out.read_bytes()


def test_stored_folders_become_keys_and_a_release_exports_the_same_bytes(tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "db").mkdir()
    url = f"sqlite:///{tmp_path / 'db' / 'v3d.sqlite3'}"
    command.upgrade(alembic_config(url), "0034")
    data = tmp_path / "data"
    monkeypatch.setenv("V3D_DATA_ROOT", str(data))  # what the migrating process's settings name
    monkeypatch.delenv("V3D_STORAGE_URL", raising=False)
    monkeypatch.delenv("V3D_JOBS_DIR", raising=False)
    get_settings.cache_clear()
    settings = Settings(_env_file=None, database_url=url, calibration_workers=1, data_root=data)
    upload, under_root, elsewhere = jobs_dir(settings) / "uploads" / "u1", data / "sn" / "v3", tmp_path / "elsewhere"
    engine = make_engine(url)
    try:
        with Session(engine) as session:
            # the rows as the current models read and write them hold columns of later revisions (0038, a release's
            # export settings; 0039, a 3D ball's sigma; 0040, what backs the ball; 0041, the batch that accepted a
            # system): added while this revision's code runs, dropped before the upgrade, which adds them
            session.execute(sa.text("ALTER TABLE triangulations ADD COLUMN sigma_m FLOAT"))
            session.execute(sa.text("ALTER TABLE systems ADD COLUMN ball_evidence VARCHAR(11) DEFAULT 'none' NOT NULL"))
            session.execute(sa.text("ALTER TABLE systems ADD COLUMN ball_evidence_reasons JSON DEFAULT '[]' NOT NULL"))
            session.execute(sa.text("ALTER TABLE review_decisions ADD COLUMN batch_id INTEGER"))
            game = make_game(session)
            for k, folder in enumerate((upload, under_root, elsewhere), 1):
                folder.mkdir(parents=True)
                system_id = make_system(session, settings, game, f"{k}.png", image_dir=folder).system_id
                system = session.get(System, system_id)
                assert system is not None
                system.review = ReviewDecision(status=ReviewStatus.ACCEPTED)
                system.review_status = ReviewStatus.ACCEPTED
                session.commit()
            session.execute(sa.text("ALTER TABLE releases ADD COLUMN export_settings JSON"))
            create_release(session, "v1")
            assert _roots(session) == {str(upload.resolve()), str(under_root.resolve()), str(elsewhere.resolve())}
            before = _export(session, settings, tmp_path / "before.zip")
            session.execute(sa.text("ALTER TABLE releases DROP COLUMN export_settings"))
            session.execute(sa.text("ALTER TABLE triangulations DROP COLUMN sigma_m"))
            session.execute(sa.text("ALTER TABLE review_decisions DROP COLUMN batch_id"))
            session.execute(sa.text("ALTER TABLE systems DROP COLUMN ball_evidence"))
            session.execute(sa.text("ALTER TABLE systems DROP COLUMN ball_evidence_reasons"))
            session.commit()

            command.upgrade(alembic_config(url), "head")
            assert _roots(session) == {"storage:uploads/u1", "data-root:sn/v3", str(elsewhere.resolve())}
            after = _export(session, settings, tmp_path / "after.zip")
            assert after == before and b"Frames-v3.zip" in after  # images in the zip, byte for byte

            command.downgrade(alembic_config(url), "0034")
            assert _roots(session) == {str(upload.resolve()), str(under_root.resolve()), str(elsewhere.resolve())}
    finally:
        engine.dispose()
        get_settings.cache_clear()
