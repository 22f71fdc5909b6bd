"""The same import, recompute, edit and export on PostgreSQL as on SQLite (JSONB, DOUBLE PRECISION,
timestamptz, savepoints)."""
from __future__ import annotations

import pytest
import sqlalchemy as sa

from app.db.models import Frame, System
from app.db.session import make_engine, make_session_factory
from app.services.curation.decisions import decide_review
from app.services.curation.editing import update_ball_label
from app.services.transfer.exporting import export_soccernet_v3d
from app.services.transfer.importing import import_soccernet_v3, import_soccernet_v3d

from .transfer.test_exporting import _snapshot


@pytest.mark.postgres
def test_import_recompute_edit_export_round_trip_on_postgres(pg_migrated_url, settings, v3_tree, tmp_path,
                                                             fresh_session_factory):
    engine = make_engine(pg_migrated_url)
    try:
        with make_session_factory(engine)() as pg:
            first = import_soccernet_v3(pg, v3_tree, settings)
            assert (first.systems_new, first.frames) == (3, 8)
            system = pg.scalars(sa.select(System).where(System.name == "2.png")).one()
            assert len(system.frames) == 4 and system.triangulation is not None
            frame = next(f for f in system.frames if f.name == "2_3.png")
            update_ball_label(pg, frame.id, box=[b + 2.5 for b in frame.ball_label.box], settings=settings)
            decide_review(pg, system_id=system.id, status="accepted", comment="checked on PostgreSQL")
            again = import_soccernet_v3(pg, v3_tree, settings)
            assert (again.systems_new, again.systems_changed) == (0, 0)

            pg.expire_all()
            frame = pg.get(Frame, frame.id)
            assert frame.ball_label.edited and frame.ball_label.edited_at.tzinfo is not None
            export_soccernet_v3d(pg, tmp_path / "export", include_all=True)
            on_pg = _snapshot(pg)
        lite = fresh_session_factory("from-pg")
        try:
            import_soccernet_v3d(lite, tmp_path / "export", settings)
            assert _snapshot(lite) == on_pg  # the same numbers on both backends
        finally:
            lite.close()
    finally:
        engine.dispose()
