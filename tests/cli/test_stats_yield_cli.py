"""``v3d stats yield --truth``: a truth file that is not a synthetic set's truth, whatever its shape or size, exits 2
printing ``Error: --truth <file>: ...`` with words naming the place, before any database is opened: never a
traceback, never a count of the systems it could not read."""
from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

import app.cli.detectors  # noqa: F401  # registers its commands
from app.cli._root import cli

runner = CliRunner()

GOOD_SYSTEM = '{"action": "1_0.png", "ball_3d": [1.0, 2.0, 0.11]}'


@pytest.mark.parametrize(("text", "words"), [
    ("[]", "an object with a 'games' list"),
    ('{"games": 7}', "an object with a 'games' list"),
    ('{"games": [3]}', "games[0]: expected a game"),
    ('{"games": [{"systems": []}]}', "games[0].match: expected the game's match"),
    ('{"games": [{"match": "m", "systems": 7}]}', "games[0].systems: expected a list of systems"),
    ('{"games": [{"match": "m", "systems": [' + GOOD_SYSTEM + ', "x"]}]}', "games[0].systems[1]: expected a system"),
    ('{"games": [{"match": "m", "systems": [{"ball_3d": null}]}]}', "games[0].systems[0].action"),
    ('{"games": [{"match": "m", "systems": [{"action": "a", "ball_3d": [NaN, 1, 2]}]}]}',
     "games[0].systems[0].ball_3d: expected three finite numbers"),
    ('{"games": [{"match": "m", "systems": [{"action": "a", "ball_3d": [1, 2]}]}]}',
     "games[0].systems[0].ball_3d: expected three finite numbers"),
    ('{"games": [{"match": "m", "systems": [{"action": "a", "ball_3d": [1, 2, "3"]}]}]}',
     "games[0].systems[0].ball_3d: expected three finite numbers"),
    ('{"games": [{"match": "m", "systems": [{"action": "a", "ball_3d": [1, 2, 1e999]}]}]}',
     "games[0].systems[0].ball_3d: expected three finite numbers"),
    ('{"games": ' + "[" * 100_000 + "]" * 100_000 + "}", "nested too deep"),
    ('{"games": [{"match": "m", "systems": [{"action": "a", "ball_3d": [' + "7" * 5000 + ', 1, 2]}]}]}',
     "more than 4300 digits"),
    ("{\"games\": [{\"match\": \"m\xe9\"}]}".encode("latin-1"), "not UTF-8"),
    ('{"games": [', "invalid or truncated JSON"),
], ids=["list", "games-number", "game-number", "no-match", "systems-number", "system-text", "no-action", "nan",
        "short-ball", "text-in-ball", "infinite", "deep", "long-number", "latin-1", "truncated"])
def test_a_truth_file_of_the_wrong_shape_exits_2_in_words(tmp_path: Path, text: str | bytes, words: str) -> None:
    truth = tmp_path / "truth.json"
    if isinstance(text, bytes):
        truth.write_bytes(text)
    else:
        truth.write_text(text)
    never_opened = tmp_path / "never.sqlite3"
    res = runner.invoke(cli, ["stats", "yield", "--truth", str(truth), "--database-url", f"sqlite:///{never_opened}"])
    assert res.exit_code == 2, (res.output, res.exception)
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"Error: --truth {truth}: ") and words in lines[0], res.output
    assert "Traceback" not in res.output and "with a 3D ball" not in res.output
    assert not never_opened.exists()  # refused before the database is touched
