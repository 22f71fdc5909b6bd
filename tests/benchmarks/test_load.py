"""``benchmarks/load.py`` runs: annotators editing at once against ``v3d serve --workers 2`` (a real server, two
processes) on the demo, 4 annotators x 6 edits each in CI's suite and 20 x 25 (the benchmark's 500 edits) in the
slow tier, on SQLite and on PostgreSQL (skipped when the local server is
down): no 5xx, no transport error, no lost edit, no lost recomputation."""
from __future__ import annotations

import shutil

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from app.core.config import Settings
from app.main import create_app
from benchmarks import load
from tests.accounts import as_token, make_accounts
from tests.conftest import PG_ADMIN_URL, sizes


@pytest.fixture(scope="module")
def demo_sqlite(tmp_path_factory: pytest.TempPathFactory):
    """A SQLite file holding the demo, imported once for this module (copied by each run)."""
    template = tmp_path_factory.mktemp("load") / "demo.sqlite3"
    with load.fresh_database(None) as url:
        from sqlalchemy.engine import make_url

        from app.db.session import make_engine

        engine = make_engine(url)
        with engine.connect() as conn:
            conn.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)")  # everything in the main file
        engine.dispose()
        shutil.copyfile(make_url(url).database, template)
    return template


def _postgresql() -> str:
    engine = sa.create_engine(PG_ADMIN_URL)
    try:
        with engine.connect():
            return PG_ADMIN_URL
    except sa.exc.OperationalError as exc:
        pytest.skip(f"PostgreSQL not reachable at {PG_ADMIN_URL}: {exc.orig}")
    finally:
        engine.dispose()


@pytest.mark.parametrize("size", sizes((4, 24), (20, 500)))
@pytest.mark.parametrize("backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def test_concurrent_edits_on_two_workers_are_all_accepted_and_kept(backend: str, size: tuple[int, int], tmp_path,
                                                                   demo_sqlite) -> None:
    url = _postgresql() if backend == "postgresql" else None
    clients, edits = size
    report = load.run_load(url, clients=clients, edits=edits, workers=2, timeout_s=60.0, max_seconds=900.0,
                           log=tmp_path / "serve.log", template=demo_sqlite, users=True, if_match=True, audit=True)
    figures = report.summary()
    assert figures["edits_sent"] == edits and not report.stopped_by_deadline, figures
    assert (figures["2xx"], figures["5xx"], figures["error"]) == (edits, 0, 0), (
        figures, (tmp_path / "serve.log").read_text()[-2000:])
    assert report.lost_edits == [] and report.lost_recomputations == [], figures
    assert figures["p95_ms"] > 0


def test_the_checks_catch_a_lost_edit_and_a_stale_recomputation(demo_sqlite) -> None:
    """The checks themselves can fail: an answer or a final state that shows another box than the last
    accepted edit is a lost edit, and a stored 3D ball that a recomputation from the stored labels does
    not give back is a lost recomputation (the demo database, served in-process)."""
    from app.db.models import Triangulation
    from app.db.session import make_engine, make_session_factory

    report = load.LoadReport(clients=1, edits_total=1, workers=1, backend="sqlite")
    with load.fresh_database(None, template=demo_sqlite) as url:
        admin = make_accounts(url, login=False, roles=("admin",))["admin"]
        with as_token(TestClient(create_app(Settings(database_url=url))), admin) as client:
            views = load.labelled_views(client)
            system_id, frame_id, box, _, _ = views[0]
            sent = load.edit_box(box, 0, 0)  # "accepted", but never stored, and answered with the old box
            report.edits.append(load.Edit(0, frame_id, sent, 200, 5.0, 0, shown=box))
            load.check_final_state(client, views, report, audit=False)
        engine = make_engine(url)
        with make_session_factory(engine)() as s:
            tri = s.scalars(sa.select(Triangulation).where(Triangulation.system_id == system_id)).one()
            tri.ball3d = [tri.ball3d[0] + 1.0, tri.ball3d[1], tri.ball3d[2]]  # as if computed from stale labels
            s.commit()
        engine.dispose()
        load.check_recomputations(url, sorted({v[0] for v in views}), report)
    assert len(report.lost_edits) == 2, report.lost_edits
    assert "answered" in report.lost_edits[0] and "final box" in report.lost_edits[1]
    assert report.lost_recomputations == [f"system {system_id}: stored ['ball3d'] differ from a recomputation"]
    assert not report.ok
