"""Issue 27, item 5: every CSV cell from a dataset is inert. Was: a season folder ``=HYPERLINK(...)`` and a match
``-2+3`` reached ``SNv3D.csv`` as formulas (165 cells of the dev game). Now escaped with a leading ``'`` (OWASP),
numbers untouched, and v3d's readers undo it: the export re-imports to the same names."""
from __future__ import annotations

import csv
from pathlib import Path

import sqlalchemy as sa

from app.datasets.csv_cells import FORMULA_STARTS, inert_cell, read_cell
from app.datasets.issia3d import Issia3DRow, read_issia3d_csv, write_issia3d_csv
from app.db.models import Frame, Game, System
from app.services.evaluation.boxes import read_precise_boxes
from app.services.transfer.exporting import export_soccernet_v3d
from app.services.transfer.importing import import_soccernet_v3, import_soccernet_v3d

from ..datasets import DEV_GAME, write_v3_game

#: A folder name cannot hold "/", so the link names a host without a scheme.
SEASON = '=HYPERLINK("evil.example","y")'
MATCH = "-2+3"


def _names(session) -> set[tuple[str, str, str, str, str]]:
    rows = session.execute(sa.select(Game.league, Game.season, Game.match, System.name, Frame.name)
                           .join(System, System.game_id == Game.id).join(Frame, Frame.system_id == System.id))
    return {tuple(r) for r in rows}


def test_dataset_names_reach_the_export_as_inert_cells_and_re_import_the_same(
        db_session, settings, shared_dir: Path, tmp_path: Path, fresh_session_factory) -> None:
    root = tmp_path / "v3"
    write_v3_game(shared_dir, root, game=(DEV_GAME[0], SEASON, MATCH))
    import_soccernet_v3(db_session, root, settings)
    before = _names(db_session)
    assert {(league, season, match) for league, season, match, *_ in before} == {(DEV_GAME[0], SEASON, MATCH)}

    report = export_soccernet_v3d(db_session, tmp_path / "export", include_all=True)
    with report.csv_path.open(newline="", encoding="utf-8") as fh:
        header, *rows = list(csv.reader(fh))
    assert rows and all(r[header.index("season")] == "'" + SEASON and r[header.index("match")] == "'" + MATCH
                        for r in rows)
    formulas = [c for r in rows for c in r if c.startswith(FORMULA_STARTS) and c != inert_cell(c)]
    assert formulas == []  # no cell a spreadsheet would run
    numbers = [c for r in rows for c in r if c[:1] == "-"]
    assert all(float(c) < 0 for c in numbers)  # v3d's own negative numbers stay numbers, unescaped

    fresh = fresh_session_factory("reimport")
    try:
        import_soccernet_v3d(fresh, tmp_path / "export", settings)
        assert _names(fresh) == before
    finally:
        fresh.close()


def test_one_escape_and_its_inverse_for_every_csv_v3d_reads_and_writes(tmp_path: Path) -> None:
    cells = ["=1+1", "+1", "-2+3", "@SUM(A1)", "\tx", "\rx", "'", "''=x", "'plain", "-2.5", "+3", "1e-5", "x", ""]
    assert [read_cell(inert_cell(c)) for c in cells] == cells
    assert [inert_cell(c) for c in ("=1+1", "+1", "-2.5", "1e-5", "'plain")] == ["'=1+1", "+1", "-2.5", "1e-5",
                                                                                  "''plain"]
    # ISSIA-3D.csv: only v3d's numbers and words, negative coordinates among them, written and read back as they are.
    row = Issia3DRow(frame=3, per_camera={1: (-12.5, 4.0, 0.25, 9.0, -0.5)}, num_cameras=1, ball_3d=(-1.5, 2.0, 0.11),
                     cam_list=(1,), ball_3d_smoothed=None, ball_3d_source="fitted")
    path = tmp_path / "ISSIA-3D.csv"
    write_issia3d_csv(path, [row])
    assert "-12.5,4.0,0.25,9.0,-0.5" in path.read_text()
    assert read_issia3d_csv(path)[0].per_camera[1] == (-12.5, 4.0, 0.25, 9.0, -0.5)
    # Precise boxes copied out of an export keep the names the export escaped.
    precise = tmp_path / "precise.csv"
    with precise.open("w", newline="") as fh:
        csv.writer(fh).writerows([["league", "season", "match", "image", "x1", "y1", "x2", "y2"],
                                  ["l", "'" + SEASON, "'" + MATCH, "1.png", 1, 2, 3, 4]])
    box = read_precise_boxes(precise)[0]
    assert (box.season, box.match) == (SEASON, MATCH)
