"""The cookbook runs (``examples/client/``): each example, run as a script would run it (its own process, ``V3D_URL``
and ``V3D_TOKEN``), against a served demo with the shared SoccerNet-v3 dev set uploaded by the first; what each did
is checked through the raw REST API, never through the client. The examples run in order on one server (one served
demo for the module: ``served_demo``)."""
from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import zipfile
from datetime import datetime, timezone
from pathlib import Path

import pytest

from app.core.paths import PROJECT_ROOT
from tests.client.conftest import ServedDemo, page_through, zip_of

pytestmark = [pytest.mark.processes, pytest.mark.shared]

EXAMPLES = PROJECT_ROOT / "examples" / "client"
#: A bound on one example's run that only a hung one reaches, on a loaded machine.
TIMEOUT_S = 300


def _command(served: ServedDemo, role: str, name: str, *args: object) -> tuple[list[str], dict[str, str]]:
    env = {**os.environ, "V3D_URL": served.url, "V3D_TOKEN": served.token(role)}
    return [sys.executable, str(EXAMPLES / name), *map(str, args)], env


def run_example(served: ServedDemo, role: str, name: str, *args: object, cwd: Path) -> str:
    """Run the example ``name`` with ``role``'s token in ``cwd``; its standard output (it must exit 0)."""
    command, env = _command(served, role, name, *args)
    done = subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def started() -> datetime:
    """When the module began (the activity example's SINCE)."""
    return datetime.now(timezone.utc)


@pytest.fixture(scope="module")
def dev_set(served_demo: ServedDemo, shared_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shared SoccerNet-v3 dev set as a zip, to upload."""
    folder = shared_dir / "data" / "synthetic" / "soccernet-v3-dev"
    return zip_of(folder, tmp_path_factory.mktemp("dev") / "soccernet-v3-dev.zip")


def test_01_uploads_the_dataset_and_prints_the_jobs_result(served_demo: ServedDemo, dev_set: Path, started: datetime,
                                                            tmp_path: Path) -> None:
    raw = served_demo.raw()
    games_before = {g["match"] for g in raw.get("/api/games").json()}
    out = json.loads(run_example(served_demo, "admin", "01_upload_and_wait.py", dev_set, cwd=tmp_path))
    job = raw.get(f"/api/jobs/{out['job']}").json()
    assert job["state"] == "done" and job["kind"] == "import" and out["result"] == job["result"]
    assert job["result"]["systems"] == 40 and job["result"]["frames"] == 105
    new_games = {g["match"] for g in raw.get("/api/games").json()} - games_before
    assert len(new_games) == 2 and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("kind", ["mirrored_labels", "any"])
def test_02_prints_the_ids_the_apis_filter_gives(served_demo: ServedDemo, kind: str, tmp_path: Path) -> None:
    printed = [int(line) for line in run_example(served_demo, "annotator", "02_systems_with_doubt.py", kind,
                                                 cwd=tmp_path).split()]
    expected = [s["id"] for s in page_through(served_demo.raw(), "/api/systems", doubt=kind)]
    assert printed == expected and len(expected) > 0


def test_03_two_moves_started_together_on_one_frame_both_land(served_demo: ServedDemo, tmp_path: Path) -> None:
    raw = served_demo.raw()
    frame = next(f for f in page_through(raw, "/api/frames", sort="name")
                 if f["ball"]["box"] is not None and f["ball"]["box"][0] > 100 and f["ball"]["box"][1] > 100
                 and f["ball"]["box"][2] < f["width"] - 100 and f["ball"]["box"][3] < f["height"] - 100)
    before = raw.get(f"/api/frames/{frame['id']}").json()["ball"]["box"]
    runs = []
    for dx, dy in ((4, 0), (0, 3)):
        command, env = _command(served_demo, "annotator", "03_move_ball.py", frame["id"], dx, dy)
        runs.append(subprocess.Popen(command, env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True))
    for run in runs:
        _, err = run.communicate(timeout=TIMEOUT_S)
        assert run.returncode == 0, err
    after = raw.get(f"/api/frames/{frame['id']}").json()["ball"]["box"]
    assert after == pytest.approx([before[0] + 4, before[1] + 3, before[2] + 4, before[3] + 3])
    moves = [e for e in page_through(raw, "/api/audit", frame_id=frame["id"]) if e["actor"] == "test-annotator"]
    assert len(moves) == 2


def test_04_leaves_no_label_doubt_with_a_fix_it_could_apply(served_demo: ServedDemo, tmp_path: Path) -> None:
    raw = served_demo.raw()
    out = json.loads(run_example(served_demo, "annotator", "04_apply_fixes.py", cwd=tmp_path))
    assert out["applied"], "the dev set's corrupted systems have fixes to apply"
    tried = {(f["frame"], f["action"]) for f in out["applied"] + out["refused"]}
    assert len(tried) == len(out["applied"]) + len(out["refused"])  # no fix twice on one view
    left = []
    for summary in page_through(raw, "/api/systems", doubt="any"):
        system = raw.get(f"/api/systems/{summary['id']}").json()
        left += [(d["frame_id"], d["suggestion"]["action"]) for d in system["doubts"]
                 if d["accuses_label"] and (d["suggestion"] or {}).get("request")
                 and (d["frame_id"], d["suggestion"]["action"]) not in tried]
    assert left == []
    entries = [e for e in page_through(raw, "/api/audit", user="test-annotator")]
    assert len([e for e in entries if e["frame_id"] in {f for f, _ in tried}]) >= len(out["applied"])


def test_05_accepts_only_pending_systems_with_no_doubt_and_a_3d_ball(served_demo: ServedDemo,
                                                                     tmp_path: Path) -> None:
    raw = served_demo.raw()
    clean = {s["id"] for s in page_through(raw, "/api/systems", status="pending", doubt="none")
             if s["ball3d"] is not None}
    accepted_before = {s["id"] for s in page_through(raw, "/api/systems", status="accepted")}
    printed = int(run_example(served_demo, "reviewer", "05_accept_clean.py", cwd=tmp_path).strip())
    accepted_after = {s["id"] for s in page_through(raw, "/api/systems", status="accepted")}
    assert accepted_after - accepted_before == clean and printed == len(clean) > 0


def test_06_downloads_the_release_export_byte_for_byte(served_demo: ServedDemo, tmp_path: Path) -> None:
    raw = served_demo.raw()
    run_example(served_demo, "admin", "06_release.py", "cookbook-1", "cookbook-1.zip", cwd=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cookbook-1.zip"]
    release = raw.get("/api/releases/cookbook-1").json()
    assert release["systems"] == len(page_through(raw, "/api/systems", status="accepted"))
    answer = raw.get("/api/exports/soccernet-v3d", params={"release": "cookbook-1"})
    assert answer.status_code == 200
    assert (tmp_path / "cookbook-1.zip").read_bytes() == answer.content
    with zipfile.ZipFile(tmp_path / "cookbook-1.zip") as zf:
        assert "SNv3D.csv" in zf.namelist()


def test_07_imports_the_predictions_and_prints_the_sources(served_demo: ServedDemo, tmp_path: Path) -> None:
    raw = served_demo.raw()
    games = {s["id"]: s["game"] for s in page_through(raw, "/api/systems")}
    frames = [f for f in page_through(raw, "/api/frames", sort="name") if f["ball"]["box"] is not None][:5]
    path = tmp_path / "detections.csv"
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["league", "season", "match", "image", "x1", "y1", "x2", "y2", "score"])
        for frame in frames:
            game = games[frame["system_id"]]
            writer.writerow([game["league"], game["season"], game["match"], frame["name"], *frame["ball"]["box"], 0.9])
    printed = json.loads(run_example(served_demo, "admin", "07_predictions.py", path, "cookbook-detector",
                                     cwd=tmp_path))
    stored = raw.get("/api/predictions").json()["items"]
    assert [(s["source"], s["predictions"], s["frames"]) for s in printed] == \
        [(s["source"], s["predictions"], s["frames"]) for s in stored]
    assert ("cookbook-detector", 5, 5) in [(s["source"], s["predictions"], s["frames"]) for s in stored]


def test_08_prints_the_raw_figures_and_audit_since(served_demo: ServedDemo, started: datetime,
                                                   tmp_path: Path) -> None:
    raw = served_demo.raw("reviewer")
    out = json.loads(run_example(served_demo, "reviewer", "08_activity.py", started.isoformat(), cwd=tmp_path))
    figures = raw.get("/api/stats/annotators", params={"since": started.isoformat()}).json()["items"]
    assert out["annotators"] == figures
    entries = [e for e in page_through(raw, "/api/audit") if datetime.fromisoformat(e["at"]) >= started]
    assert [e["id"] for e in out["audit"]] == [e["id"] for e in entries] and entries
    assert [(e["actor"], e["action"], e["summary"]) for e in out["audit"]] == \
        [(e["actor"], e["action"], e["summary"]) for e in entries]
