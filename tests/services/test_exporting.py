"""SoccerNet-v3D export: the files and their columns, and an export -> import round trip that
reproduces every label, camera and number."""
from __future__ import annotations

import csv
import json

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import selectinload

from app.db.models import CalibrationSource, Frame, Game, ReviewStatus, System
from app.services.curation.editing import decide_review, replace_field_lines, update_ball_label
from app.services.kinds import split_of
from app.services.transfer.exporting import CSV_COLUMNS, export_soccernet_v3d
from app.services.transfer.importing import import_sn_calibration, import_soccernet_v3, import_soccernet_v3d

from .datasets import DEV_GAME, write_calibration_zip

SECTION_9_COLUMNS = ["league", "season", "match", "main_action", "action", "replay", "img_w", "img_h", "is_ball",
                     "ball_bbox", "calibration", "JaC@0.005", "JaC@0.01", "JaC@0.02", "ball_3D", "rep_error",
                     "optimized_error", "optimized_d", "set"]


def _systems(session) -> dict[str, System]:
    return {s.name: s for s in session.scalars(sa.select(System))}


def test_only_accepted_systems_are_exported_by_default(db_session, settings, imported, tmp_path):
    systems = imported
    refused = next(f for f in systems["2.png"].frames if f.name == "2_1.png")
    replace_field_lines(db_session, refused.id, refused.field_lines.lines, settings=settings)  # one line: refused
    empty = export_soccernet_v3d(db_session, tmp_path / "none")
    assert (empty.systems, empty.rows, empty.label_files) == (0, 0, ())
    assert (tmp_path / "none" / "SNv3D.csv").read_text().splitlines() == [",".join(CSV_COLUMNS)]

    decide_review(db_session, system_id=systems["2.png"].id, status="accepted")
    decide_review(db_session, system_id=systems["3.png"].id, status="rejected")
    report = export_soccernet_v3d(db_session, tmp_path / "out")
    assert (report.games, report.systems, report.rows) == (1, 1, 4)

    labels_path = (tmp_path / "out").joinpath(*DEV_GAME, "Labels-v3D.json")
    assert report.label_files == (labels_path,)
    doc = json.loads(labels_path.read_text())
    assert list(doc["actions"]) == ["2.png"] and list(doc["replays"]) == ["2_1.png", "2_2.png", "2_3.png"]
    assert doc["GameMetadata"]["reconstructions"] == ["2.png"]
    action = doc["actions"]["2.png"]
    assert refused.calibration.camera is None
    assert action["imageMetadata"]["calibrated_replays"] == ["2_2.png", "2_3.png"]  # 2_1.png is refused
    frame = systems["2.png"].frames[0]
    assert action["calibration"] == frame.calibration.camera
    assert action["JaC"] == {"JaC@0.005": frame.calibration.jac_0005, "JaC@0.01": frame.calibration.jac_001,
                             "JaC@0.02": frame.calibration.jac_002}
    assert doc["replays"]["2_1.png"]["calibration"] is None and doc["replays"]["2_1.png"]["linked_action"] == "2.png"

    with (tmp_path / "out" / "SNv3D.csv").open() as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
    assert reader.fieldnames[:len(SECTION_9_COLUMNS)] == SECTION_9_COLUMNS
    first, replay = rows[0], rows[1]
    assert (first["main_action"], first["action"], first["replay"]) == ("2.png", "True", "")
    assert (replay["main_action"], replay["action"], replay["replay"]) == ("2.png", "False", "2_1.png")
    assert json.loads(first["ball_bbox"]) == frame.ball_label.box
    assert json.loads(first["ball_3D"]) == systems["2.png"].triangulation.ball3d
    assert float(first["rep_error"]) == frame.reprojection.error_px
    assert float(first["optimized_d"]) == frame.optimised_box.d_opt_px
    assert float(first["optimized_error"]) == frame.optimised_box.error_m
    assert json.loads(first["calibration"]) == frame.calibration.camera
    assert float(first["JaC@0.005"]) == frame.calibration.jac_0005
    assert (int(first["img_w"]), int(first["img_h"]), first["is_ball"]) == (frame.width, frame.height, "True")
    assert replay["calibration"] == "" and replay["JaC@0.005"] == ""  # refused view: empty cells
    assert {r["set"] for r in rows} == {split_of("/".join(DEV_GAME))}


def test_split_is_deterministic_and_about_80_20():
    games = [f"league/season/game {i}" for i in range(2000)]
    splits = [split_of(g) for g in games]
    assert splits == [split_of(g) for g in games]
    assert 0.77 < splits.count("train") / len(splits) < 0.83


def _snapshot(session) -> dict:
    """Every label, camera and number of the database, keyed by natural keys (no ids)."""
    out = {}
    frames = session.scalars(sa.select(Frame).options(selectinload("*"))).all()
    for f in frames:
        s = f.system
        key = (s.game.league, s.game.season, s.game.match, s.name, f.name)
        cal, lab, fl, opt, rep = f.calibration, f.ball_label, f.field_lines, f.optimised_box, f.reprojection
        tri = s.triangulation
        names = {fr.id: fr.name for fr in s.frames}
        out[key] = {
            "frame": (f.role, f.position, f.width, f.height, f.image_zip, f.image_member, f.image_path, s.kind,
                      s.review.status),
            "lines": (fl.lines, fl.original_lines),
            "ball": None if lab is None else (lab.kind, lab.box, lab.point, lab.original_kind, lab.original_box,
                                              lab.original_point),
            "calibration": (cal.status, cal.camera, cal.jac(), cal.reason, cal.flags, cal.residuals_px, cal.admitted),
            "triangulation": (tri.status, tri.ball3d, tri.tau_px, tri.rule, tri.min_baseline_m, [
                (names[p.frame_a_id], names[p.frame_b_id], p.point, p.error_px, p.parallax_deg, p.baseline_m, p.kept,
                 p.reason) for p in tri.pairs]),
            "optimised": None if opt is None else (opt.box, opt.d_opt_px, opt.error_m),
            "reprojection": None if rep is None else (rep.point, rep.error_px),
        }
    return out


def test_export_then_import_reproduces_every_label_camera_and_number(
        db_session, settings, v3_tree, shared_dir, tmp_path, fresh_session_factory):
    import_soccernet_v3(db_session, v3_tree, settings)
    import_sn_calibration(db_session, write_calibration_zip(shared_dir, tmp_path / "wc" / "a.zip"), settings,
                          width=960, height=540)
    systems = _systems(db_session)
    f = next(fr for fr in systems["2.png"].frames if fr.name == "2_2.png")
    update_ball_label(db_session, f.id, box=[b + 3.25 for b in f.ball_label.box], settings=settings)
    g = next(fr for fr in systems["3.png"].frames if fr.name == "3_1.png")
    update_ball_label(db_session, g.id, point=[321.5, 123.25], settings=settings)
    one = systems["1"].frames[0]
    replace_field_lines(db_session, one.id, {k: v for k, v in one.field_lines.lines.items()}, settings=settings)
    decide_review(db_session, system_id=systems["2.png"].id, status="accepted")
    decide_review(db_session, system_id=systems["0.png"].id, status="needs_fix")

    report = export_soccernet_v3d(db_session, tmp_path / "export", include_all=True)
    assert (report.games, report.systems) == (2, 6)

    fresh = fresh_session_factory("reimported")
    try:
        back = import_soccernet_v3d(fresh, tmp_path / "export", settings)
        assert (back.games, back.systems, back.frames, back.calibrated + back.refused) == (2, 6, 11, 11)
        original, reimported = _snapshot(db_session), _snapshot(fresh)
        assert set(original) == set(reimported)
        for key in original:
            assert reimported[key] == original[key], key
        assert all(c.source is CalibrationSource.IMPORTED for c in
                   fresh.scalars(sa.select(Frame)).all() for c in [c.calibration])
        assert fresh.scalars(sa.select(Game)).all()[0].systems[0].review.status in set(ReviewStatus)
        # importing the same export again changes nothing
        again = import_soccernet_v3d(fresh, tmp_path / "export", settings)
        assert (again.systems_new, again.systems_changed) == (0, 0)
        assert _snapshot(fresh) == reimported
    finally:
        fresh.close()


def test_v3d_import_needs_the_csv_row_of_every_frame(db_session, settings, v3_tree, tmp_path):
    from app.core.errors import DatasetError

    import_soccernet_v3(db_session, v3_tree, settings)
    export_soccernet_v3d(db_session, tmp_path / "export", include_all=True)
    csv_path = tmp_path / "export" / "SNv3D.csv"
    lines = csv_path.read_text().splitlines()
    csv_path.write_text("\n".join(lines[:-1]) + "\n")  # drop the last frame's row
    with pytest.raises(DatasetError, match=r"SNv3D.csv: no row for .* frame '3_1.png'"):
        import_soccernet_v3d(db_session, tmp_path / "export", settings)
    csv_path.write_text("\n".join(lines).replace('"[', '"[NaN, ', 1) + "\n")  # a NaN in the first box
    with pytest.raises(DatasetError, match=r"SNv3D.csv: line 2 \(.*\): .*"):
        import_soccernet_v3d(db_session, tmp_path / "export", settings)


def test_v3d_csv_cells_are_read_flexibly(db_session, settings, imported, tmp_path, fresh_session_factory):
    """Boxes as Python tuples, booleans as 1/0, "NaN" for missing replays: what pandas writes."""
    export_soccernet_v3d(db_session, tmp_path / "export", include_all=True)
    csv_path = tmp_path / "export" / "SNv3D.csv"
    with csv_path.open() as fh:
        reader = csv.DictReader(fh)
        fields, rows = reader.fieldnames, list(reader)
    for row in rows:
        if row["ball_bbox"]:
            row["ball_bbox"] = repr(tuple(json.loads(row["ball_bbox"])))
        row["action"], row["is_ball"] = ("1" if row["action"] == "True" else "0"), row["is_ball"].lower()
        row["replay"] = row["replay"] or "NaN"
    with csv_path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    fresh = fresh_session_factory("flexible")
    try:
        import_soccernet_v3d(fresh, tmp_path / "export", settings)
        assert _snapshot(fresh) == _snapshot(db_session)
    finally:
        fresh.close()
