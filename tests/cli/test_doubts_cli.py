"""``v3d doubts``: every system's stored doubts, as a table of counts per kind and as JSON, on the demo
imported through ``v3d import`` (a temporary SQLite file)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

import app.cli.datasets  # registers the import commands
import app.cli.doubts  # noqa: F401  # registers v3d doubts
from app.cli._root import cli
from app.demo import generate_demo_dataset
from app.geometry.doubts import LABEL_KINDS

runner = CliRunner()


@pytest.fixture(scope="module")
def demo_db(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict]:
    root = tmp_path_factory.mktemp("doubts-cli")
    dataset = generate_demo_dataset(root / "demo")
    url = f"sqlite:///{root / 'cli.sqlite3'}"
    result = runner.invoke(cli, ["import", "soccernet-v3", str(dataset), "--database-url", url, "--workers", "1"])
    assert result.exit_code == 0, result.output
    truth = json.loads((root / "demo" / "demo-truth.json").read_text())
    return url, truth


def test_doubts_json_names_systems_and_frames_by_image_name(demo_db, tmp_path: Path) -> None:
    url, truth = demo_db
    out = tmp_path / "doubts.json"
    result = runner.invoke(cli, ["doubts", "--json", str(out), "--database-url", url])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    systems = report["systems"]
    game = truth["game"]
    assert [s["system"] for s in systems] == [s["action"] for s in truth["systems"]]
    assert all(s["game"] == {"league": game["league"], "season": game["season"], "match": game["match"]}
               for s in systems)
    images = {s["action"]: {v["image"] for v in s["views"]} for s in truth["systems"]}
    for s in systems:
        for d in s["doubts"]:
            assert set(d) >= {"kind", "frame", "message", "evidence", "suggestion"}
            assert d["frame"] is None or d["frame"] in images[s["system"]]
            assert isinstance(d["message"], str) and d["message"]
    (missing,) = truth["problems"]["missing_ball"]
    named = [d for s in systems for d in s["doubts"] if d["kind"] == "ball_missing" and d["frame"] == missing]
    assert len(named) == 1
    assert named[0]["suggestion"]["action"] == "snap_box" and len(named[0]["suggestion"]["box"]) == 4
    req = named[0]["suggestion"]["request"]
    # the label a fix makes keeps where it came from: not independent evidence until a person places it
    assert req == {"method": "PATCH", "path": f"/api/frames/{named[0]['frame_id']}/ball",
                   "body": {"box": [round(v) for v in named[0]["suggestion"]["box"]],
                            "provenance": {"doubt": "ball_missing", "code": "consensus",
                                           "from_views": named[0]["evidence"]["agreeing_views"]}}}


def test_doubts_table_counts_every_label_kind(demo_db) -> None:
    url, _ = demo_db
    result = runner.invoke(cli, ["doubts", "--database-url", url])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("9 system(s), ")
    rows = {line.split()[0]: line.split()[1:3] for line in lines[2:]}
    assert set(LABEL_KINDS) <= set(rows)
    assert int(rows["ball_missing"][0]) >= 1 and int(rows["mirrored_labels"][0]) >= 1


def test_the_misplaced_ball_is_offered_the_true_box_with_its_uncertainty(demo_db, tmp_path: Path) -> None:
    """The demo's planted wrong ball box (known truth): its ``ball_off_consensus`` doubt offers, as the one-key
    fix, the box the other views agree on, within a few px of the true ball's box and within its stated
    uncertainty; excluding the view stays offered."""
    url, truth = demo_db
    out = tmp_path / "doubts.json"
    assert runner.invoke(cli, ["doubts", "--json", str(out), "--database-url", url]).exit_code == 0
    (wrong,) = truth["problems"]["wrong_ball_box"]
    true_view = next(v for s in truth["systems"] for v in s["views"] if v["image"] == wrong)
    (doubt,) = [d for s in json.loads(out.read_text())["systems"] for d in s["doubts"]
                if d["kind"] == "ball_off_consensus" and d["frame"] == wrong]
    fix = doubt["suggestion"]
    assert fix["action"] == "snap_box" and fix["alternatives"] == ["exclude_view"]
    box, precise = fix["box"], true_view["precise_box"]
    centre_error = ((box[0] + box[2] - precise[0] - precise[2]) ** 2
                    + (box[1] + box[3] - precise[1] - precise[3]) ** 2) ** 0.5 / 2
    assert centre_error < 3.0, (box, precise)
    assert max(abs(a - b) for a, b in zip(box, precise, strict=False)) < 3.0
    assert 0.0 < fix["box_sigma_px"] < 5.0 and centre_error < 3 * fix["box_sigma_px"] + 1.0
    # the page's fix key sends the box as a suggestion (its provenance), not as a person's label
    assert fix["request"]["body"]["provenance"]["doubt"] == "ball_off_consensus"
