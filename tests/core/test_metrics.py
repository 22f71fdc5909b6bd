"""The metrics' multiprocess folder that ``v3d serve --workers N`` prepares before its workers start."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from app.core.metrics import MULTIPROC_ENV, job_families, prepare_multiprocess_dir


def test_a_given_folder_is_made_and_emptied_of_an_earlier_runs_counts(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "metrics"
    monkeypatch.setenv(MULTIPROC_ENV, str(folder))
    assert prepare_multiprocess_dir() == folder and folder.is_dir()
    (folder / "counter_123.db").write_bytes(b"old")
    (folder / "notes.txt").write_text("kept")
    assert prepare_multiprocess_dir() == folder
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt"]


def test_without_a_folder_a_new_one_is_made_for_the_workers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(MULTIPROC_ENV, "")
    monkeypatch.delenv(MULTIPROC_ENV)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # read TMPDIR again
    folder = prepare_multiprocess_dir()
    assert folder.parent == tmp_path and folder.name.startswith("v3d-metrics-") and folder.is_dir()
    assert os.environ[MULTIPROC_ENV] == str(folder)  # what the workers inherit


def test_job_gauges_name_every_kind_and_state() -> None:
    by, queued = job_families({("import", "queued"): 2, ("export", "queued"): 1, ("import", "done"): 5},
                              ["import", "export"], ["queued", "done"])
    assert {(s.labels["kind"], s.labels["state"]): s.value for s in by.samples} == {
        ("import", "queued"): 2, ("import", "done"): 5, ("export", "queued"): 1, ("export", "done"): 0}
    assert [s.value for s in queued.samples] == [3]
