"""``v3d import`` as a job, ``v3d jobs list`` and ``v3d jobs run`` on a temporary SQLite file."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

import app.cli.datasets  # registers the commands
import app.cli.jobs  # noqa: F401  # registers its commands
from app.cli._root import cli
from app.db.session import make_engine, make_session_factory
from app.services.jobs import runner as jobs
from tests.services.datasets import write_calibration_zip, write_v3_game

runner = CliRunner()


@pytest.fixture
def url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'cli.sqlite3'}"


def test_import_jobs_are_listed_with_their_outcome(shared_dir: Path, tmp_path: Path, url: str) -> None:
    archive = write_calibration_zip(shared_dir, tmp_path / "wc" / "annotations.zip")
    ok = runner.invoke(cli, ["import", "sn-calibration", str(archive), "--width", "960", "--height", "540",
                             "--database-url", url, "--workers", "1"])
    assert ok.exit_code == 0 and "(job 1)" in ok.output, ok.output
    broken = write_calibration_zip(shared_dir, tmp_path / "bad" / "annotations.zip",
                                   extra={"9.json": b'{"Middle line": [{"x": "a", "y": 0.2}]}'})
    failed = runner.invoke(cli, ["import", "sn-calibration", str(broken), "--width", "960", "--height", "540",
                                 "--database-url", url, "--workers", "1"])
    assert failed.exit_code == 2 and "Error: " in failed.output and "9.json" in failed.output, failed.output
    listed = runner.invoke(cli, ["jobs", "list", "--database-url", url])
    assert listed.exit_code == 0, listed.output
    lines = listed.output.splitlines()
    assert lines[0].split()[:3] == ["2", "import", "failed"] and "9.json" in lines[1]
    assert lines[2].split()[:3] == ["1", "import", "done"] and str(archive.resolve()) in lines[2]
    assert lines[-1] == "2 of 2 job(s)"
    only = runner.invoke(cli, ["jobs", "list", "--state", "done", "--database-url", url])
    assert only.output.splitlines()[-1] == "1 of 1 job(s)"
    bad = runner.invoke(cli, ["jobs", "list", "--state", "finished", "--database-url", url])
    assert bad.exit_code == 2 and "unknown state 'finished'" in bad.output


def test_jobs_run_runs_the_queued_jobs(url: str) -> None:
    assert runner.invoke(cli, ["jobs", "list", "--database-url", url]).output.strip() == "0 of 0 job(s)"
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            queued = jobs.submit(session, "recompute", {})
    finally:
        engine.dispose()
    ran = runner.invoke(cli, ["jobs", "run", "--database-url", url])
    assert ran.exit_code == 0 and ran.output.strip() == f"job {queued.id} (recompute): done", ran.output
    assert runner.invoke(cli, ["jobs", "run", "--database-url", url]).output == ""


def test_recompute_and_export_show_their_progress_and_counts(shared_dir: Path, tmp_path: Path, url: str) -> None:
    """``v3d recompute`` is a job run here with a progress bar and one audit entry; ``v3d export`` draws the
    games it writes."""
    from app.db.models import AuditEntry, Job

    archive = write_calibration_zip(shared_dir, tmp_path / "wc" / "annotations.zip")
    assert runner.invoke(cli, ["import", "sn-calibration", str(archive), "--width", "960", "--height", "540",
                               "--database-url", url, "--workers", "1"]).exit_code == 0
    ran = runner.invoke(cli, ["recompute", "--database-url", url])
    assert ran.exit_code == 0, ran.output
    counted = re.search(r"recomputed (\d+) system\(s\), (\d+) triangulated \(job (\d+)\)", ran.output)
    assert "recomputing systems" in ran.output and counted, ran.output
    n = int(counted.group(1))
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            job = session.query(Job).filter_by(kind="recompute").one()
            assert job.state.value == "done" and job.result["systems"] == n and job.done == job.total == n
            assert session.query(AuditEntry).filter_by(action="recompute").count() == 1
    finally:
        engine.dispose()
    # The SoccerNet-v3D export holds SoccerNet-v3 systems only (single frames leave as cameras): add one game.
    game = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), with_images=False)
    assert runner.invoke(cli, ["import", "soccernet-v3", str(game.parents[2]), "--database-url", url,
                               "--workers", "1"]).exit_code == 0
    out = runner.invoke(cli, ["export", "soccernet-v3d", str(tmp_path / "out"), "--all", "--no-images",
                              "--database-url", url])
    assert out.exit_code == 0 and "exporting games" in out.output, out.output
    assert re.search(r"exported 1 system\(s\) of 1 game\(s\)", out.output), out.output
    assert (tmp_path / "out" / "SNv3D.csv").is_file()
