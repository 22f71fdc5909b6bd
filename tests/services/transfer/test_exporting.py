"""SoccerNet-v3D export: the files and their columns, and an export -> import round trip that
reproduces every label, camera and number."""
from __future__ import annotations

import csv
import json
import zipfile

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.orm import selectinload

from app.db.models import CalibrationSource, Frame, Game, ReviewStatus, System, SystemKind, User, UserRole
from app.services.curation.decisions import decide_review
from app.services.curation.editing import replace_field_lines, update_ball_label
from app.services.kinds import split_of
from app.services.transfer.cameras_export import export_cameras
from app.services.transfer.exporting import CSV_COLUMNS, export_soccernet_v3d
from app.services.transfer.importing import import_sn_calibration, import_soccernet_v3, import_soccernet_v3d

from ..datasets import DEV_GAME, write_calibration_zip

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


def _snapshot(session, kinds=tuple(SystemKind)) -> dict:
    """Every label, camera and number of the database (of systems of ``kinds``), keyed by natural keys (no ids)."""
    out = {}
    frames = session.scalars(sa.select(Frame).options(selectinload("*"))).all()
    for f in frames:
        s = f.system
        if s.kind not in kinds:
            continue
        key = (s.game.league, s.game.season, s.game.match, s.name, f.name)
        cal, lab, fl, opt, rep = f.calibration, f.ball_label, f.field_lines, f.optimised_box, f.reprojection
        tri = s.triangulation
        names = {fr.id: fr.name for fr in s.frames}
        out[key] = {
            # images are compared by their bytes where asked: an export names no server path (its Frames-v3.zip
            # carries them)
            "frame": (f.role, f.position, f.width, f.height, s.kind, s.review.status),
            # what the release carries (player boxes, imageMetadata, links; GameMetadata): issue 19
            "release": (f.release, s.game.release),
            "lines": (fl.lines, fl.original_lines),
            "ball": None if lab is None else (lab.kind, lab.box, lab.point, lab.original_kind, lab.original_box,
                                              lab.original_point),
            "calibration": (cal.status, cal.camera, cal.jac(), cal.reason, cal.flags, cal.residuals_px, cal.admitted,
                            cal.uncertainty),
            "triangulation": (tri.status, tri.ball3d, tri.tau_px, tri.rule, tri.min_baseline_m, [
                (names[p.frame_a_id], names[p.frame_b_id], p.point, p.error_px, p.parallax_deg, p.baseline_m, p.kept,
                 p.reason) for p in tri.pairs]),
            "optimised": None if opt is None else (opt.box, opt.d_opt_px, opt.error_m),
            "reprojection": None if rep is None else (rep.point, rep.error_px),
        }
    return out


def test_export_then_import_reproduces_every_label_camera_and_number(
        db_session, settings, v3_tree, shared_dir, tmp_path, fresh_session_factory):
    """Issue 19's round trip: ``export soccernet-v3d --all`` then an import into an empty database gives the same
    games, systems, frames, field lines (original and edited), ball labels (original and edited), player boxes and
    everything else the release carries, calibrations and images, with edits made before the export; the edited
    frames' entries carry the curated lines and ball box, the imported ones under ``v3d``."""
    from app.services.images.serving import frame_image

    import_soccernet_v3(db_session, v3_tree, settings)
    import_sn_calibration(db_session, write_calibration_zip(shared_dir, tmp_path / "wc" / "a.zip"), settings,
                          width=960, height=540)
    systems = _systems(db_session)
    f = next(fr for fr in systems["2.png"].frames if fr.name == "2_2.png")
    imported_ball = f.ball_label.box
    moved = [b + 3.25 for b in imported_ball]
    update_ball_label(db_session, f.id, box=moved, settings=settings)
    g = next(fr for fr in systems["3.png"].frames if fr.name == "3_1.png")
    update_ball_label(db_session, g.id, point=[321.5, 123.25], settings=settings)
    gone = next(fr for fr in systems["0.png"].frames if fr.name == "0_1.png")
    update_ball_label(db_session, gone.id, box=None, settings=settings)  # "no ball here"
    one = next(fr for fr in systems["0.png"].frames if fr.field_lines is not None)
    first = next(iter(one.field_lines.lines))  # its first class's first polyline moved by half a pixel
    edited_lines = {k: ([[[x + 0.5, y] for x, y in v[0]], *v[1:]] if k == first else v)
                    for k, v in one.field_lines.lines.items()}
    replace_field_lines(db_session, one.id, edited_lines, settings=settings)
    assert one.field_lines.lines != one.field_lines.original_lines
    decide_review(db_session, system_id=systems["2.png"].id, status="accepted")
    db_session.add(User(name="ana", role=UserRole.ANNOTATOR, password_hash="not a hash: ana never logs in"))
    db_session.flush()
    decide_review(db_session, system_id=systems["0.png"].id, status="needs_fix", return_to="ana")

    # issue 19: the SoccerNet-v3D export holds the SoccerNet-v3 systems only; the single-view frames leave as cameras
    report = export_soccernet_v3d(db_session, tmp_path / "export", include_all=True)
    v3 = [s for s in systems.values() if s.kind is SystemKind.SOCCERNET_V3]
    assert (report.games, report.systems) == (1, len(v3))
    cams = export_cameras(db_session, tmp_path / "cameras", include_all=True)
    single = [f for s in systems.values() if s.kind is SystemKind.SINGLE_VIEW for f in s.frames
              if f.calibration is not None and f.calibration.admitted]
    assert single and cams.by_kind.get("single-view") == len(single)
    # issue 28: the layout SoccerNet's calibration evaluator reads (a predictions zip per image size)
    index = json.loads((tmp_path / "cameras" / "cameras.json").read_text())
    where = {(v["game"], v["frame"]): (s["predictions"], v["name"]) for s in index["sets"] for v in s["views"]}
    for f in single:
        zpath, name = where[(f.system.game.path, f.name)]
        with zipfile.ZipFile(tmp_path / "cameras" / zpath) as zf:
            assert json.loads(zf.read(f"camera_{name}.json")) == f.calibration.camera

    # the edited frames carry the curated values, the imported ones under v3d; the others are as imported
    source = json.loads((v3_tree.joinpath(*DEV_GAME) / "Labels-v3.json").read_text())
    doc = json.loads(report.label_files[0].read_text())
    entry = doc["replays"]["2_2.png"]
    (ball,) = [b for b in entry["bboxes"] if b["class"] == "Ball"]
    assert [ball["points"][k] for k in ("x1", "y1", "x2", "y2")] == moved
    (as_imported,) = [b for b in source["replays"]["2_2.png"]["bboxes"] if b["class"] == "Ball"]
    assert entry["v3d"]["original_ball"] == as_imported
    assert [b for b in entry["bboxes"] if b["class"] != "Ball"] == [
        b for b in source["replays"]["2_2.png"]["bboxes"] if b["class"] != "Ball"]
    for name, section in (("3_1.png", "replays"), ("0_1.png", "replays")):  # a point, a removed label: no ball box
        assert [b for b in doc[section][name]["bboxes"] if b["class"] == "Ball"] == []
        assert doc[section][name]["v3d"]["original_ball"]["class"] == "Ball"
    section = "actions" if one.role.value == "action" else "replays"
    assert doc[section][one.name]["v3d"]["original_lines"] == source[section][one.name]["lines"]
    assert doc[section][one.name]["lines"] != source[section][one.name]["lines"]
    assert doc["actions"]["2.png"]["bboxes"] == source["actions"]["2.png"]["bboxes"]
    assert doc["actions"]["2.png"]["v3d"]["original_lines"] is None
    assert doc["GameMetadata"]["UrlYoutube"] == source["GameMetadata"]["UrlYoutube"]

    fresh = fresh_session_factory("reimported")
    try:
        back = import_soccernet_v3d(fresh, tmp_path / "export", settings)
        n_frames = sum(len(s.frames) for s in v3)
        assert (back.games, back.systems,
                back.frames, back.calibrated + back.refused) == (1, len(v3), n_frames, n_frames)
        original, reimported = _snapshot(db_session, (SystemKind.SOCCERNET_V3,)), _snapshot(fresh)
        assert set(original) == set(reimported)
        for key in original:
            assert reimported[key] == original[key], key
        assert all(v["release"][0]["bboxes"] for v in reimported.values())  # the player boxes came along
        images = {f.name: b"".join(frame_image(f).chunks()) for f in db_session.scalars(sa.select(Frame))
                  if f.system.kind is SystemKind.SOCCERNET_V3}
        assert {f.name: b"".join(frame_image(f).chunks()) for f in fresh.scalars(sa.select(Frame))} == images
        # and the re-imported database exports the same document (its calibrations now "imported")
        export_soccernet_v3d(fresh, tmp_path / "again", include_all=True, images=False)
        again = json.loads((tmp_path / "again").joinpath(*DEV_GAME, "Labels-v3D.json").read_text())
        for d in (doc, again):
            for item in (*d["actions"].values(), *d["replays"].values()):
                item["v3d"]["source"] = None
        assert again == doc
        assert all(c.source is CalibrationSource.IMPORTED for c in
                   fresh.scalars(sa.select(Frame)).all() for c in [c.calibration])
        assert fresh.scalars(sa.select(Game)).all()[0].systems[0].review.status in set(ReviewStatus)
        # importing the same export again changes nothing
        again = import_soccernet_v3d(fresh, tmp_path / "export", settings)
        assert (again.systems_new, again.systems_changed) == (0, 0)
        assert _snapshot(fresh) == reimported
    finally:
        fresh.close()


def test_the_export_carries_each_games_images_and_re_imports_with_them(db_session, settings, v3_tree, tmp_path,
                                                                      fresh_session_factory):
    """Issue 15 / 19: the SoccerNet-v3D export writes each game's frames as Frames-v3.zip beside its
    Labels-v3D.json (bytes as imported, members named by the frame), so that it re-imports with its images;
    ``images=False`` leaves them out; the streamed zip holds the same."""
    import io
    import zipfile

    from app.services.images.serving import frame_image
    from app.services.transfer.export_zip import stream_soccernet_v3d_zip

    import_soccernet_v3(db_session, v3_tree, settings)
    frames = db_session.scalars(sa.select(Frame).order_by(Frame.name)).all()
    originals = {f.name: b"".join(frame_image(f).chunks()) for f in frames}
    report = export_soccernet_v3d(db_session, tmp_path / "export", include_all=True)
    assert report.images == len(originals) == 8
    (zip_path,) = (tmp_path / "export").rglob("Frames-v3.zip")
    assert zip_path.parent == (tmp_path / "export" / report.label_files[0].relative_to(tmp_path / "export")).parent
    with zipfile.ZipFile(zip_path) as zf:
        assert {i.filename: zf.read(i) for i in zf.infolist()} == originals
        assert {i.compress_type for i in zf.infolist()} == {zipfile.ZIP_STORED}

    fresh = fresh_session_factory("with-images")
    try:
        import_soccernet_v3d(fresh, tmp_path / "export", settings)
        back = {f.name: b"".join(frame_image(f).chunks()) for f in fresh.scalars(sa.select(Frame))}
        assert back == originals
    finally:
        fresh.close()

    bare = export_soccernet_v3d(db_session, tmp_path / "bare", include_all=True, images=False)
    assert bare.images == 0 and not list((tmp_path / "bare").rglob("Frames-v3.zip"))
    streamed = b"".join(stream_soccernet_v3d_zip(db_session, include_all=True))
    with zipfile.ZipFile(io.BytesIO(streamed)) as outer:
        inner_name = next(n for n in outer.namelist() if n.endswith("/Frames-v3.zip"))
        assert inner_name == zip_path.relative_to(tmp_path / "export").as_posix()
        with zipfile.ZipFile(io.BytesIO(outer.read(inner_name))) as inner:
            assert {i.filename: inner.read(i) for i in inner.infolist()} == originals
    without = b"".join(stream_soccernet_v3d_zip(db_session, include_all=True, images=False))
    assert not any(n.endswith("Frames-v3.zip") for n in zipfile.ZipFile(io.BytesIO(without)).namelist())


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


def test_a_v3d_export_whose_original_ball_disagrees_with_its_csv_is_refused(db_session, settings, v3_tree, tmp_path):
    """``v3d.original_ball`` (the imported ball entry) and the CSV's ``original_ball_bbox`` say the same: a file
    where they differ, or whose original ball is not a ball entry, is refused naming the field."""
    from app.core.errors import DatasetError

    import_soccernet_v3(db_session, v3_tree, settings)
    export_soccernet_v3d(db_session, tmp_path / "export", include_all=True, images=False)
    path = (tmp_path / "export").joinpath(*DEV_GAME, "Labels-v3D.json")
    doc = json.loads(path.read_text())
    entry = doc["actions"]["0.png"]["v3d"]
    entry["original_ball"]["points"]["x1"] += 5
    path.write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match=r"actions\['0.png'\]\.v3d\.original_ball: points .* are not the CSV's"):
        import_soccernet_v3d(db_session, tmp_path / "export", settings)
    entry["original_ball"] = {"class": "Ball", "points": [1, 2, 3, 4]}
    path.write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match=r"original_ball: expected null or a bboxes entry"):
        import_soccernet_v3d(db_session, tmp_path / "export", settings)


def test_a_v3d_export_carries_the_calibration_uncertainty_and_refuses_a_malformed_one(db_session, settings, v3_tree,
                                                                                      tmp_path):
    """The fit's standard deviations travel with the camera (the triangulation weighs views by them, issue 18): the
    export writes them under ``v3d.uncertainty``; a file whose entry is not such an object is refused naming it."""
    from app.core.errors import DatasetError

    import_soccernet_v3(db_session, v3_tree, settings)
    export_soccernet_v3d(db_session, tmp_path / "export", include_all=True, images=False)
    path = (tmp_path / "export").joinpath(*DEV_GAME, "Labels-v3D.json")
    doc = json.loads(path.read_text())
    entry = doc["actions"]["0.png"]
    stored = _systems(db_session)["0.png"].frames[0].calibration
    assert entry["v3d"]["uncertainty"] == stored.uncertainty and set(stored.uncertainty) >= {"pan_deg", "position_m"}
    for bad, message in (("x", "expected a JSON object"), ({"position_m": 3}, "malformed standard deviations")):
        entry["v3d"]["uncertainty"] = bad
        path.write_text(json.dumps(doc))
        with pytest.raises(DatasetError, match=r"actions\['0.png'\]\.v3d\.uncertainty: " + message):
            import_soccernet_v3d(db_session, tmp_path / "export", settings)


def test_a_games_frames_zip_reads_its_frames_in_one_query(db_session, settings, v3_tree, tmp_path):
    """``write_frames_zip`` reads the game's frames in one query (chunks of 500 ids), not one per frame: with one
    query a frame, the full export of the 35,550-frame scale set spent 12 of its 25 s there."""
    from sqlalchemy import event

    from app.services.transfer.exporting import write_frames_zip

    import_soccernet_v3(db_session, v3_tree, settings)
    frames = tuple((f.id, f.name) for f in db_session.scalars(sa.select(Frame).order_by(Frame.name)))
    db_session.expire_all()
    statements: list[str] = []
    engine = db_session.get_bind()
    def count(conn, cursor, statement, *rest):
        return statements.append(statement)
    event.listen(engine, "before_cursor_execute", count)
    try:
        with (tmp_path / "Frames-v3.zip").open("wb") as target:
            assert write_frames_zip(db_session, frames, target) == len(frames) == 8
    finally:
        event.remove(engine, "before_cursor_execute", count)
    assert sum(s.lstrip().upper().startswith("SELECT") and "FROM frames" in s for s in statements) == 1, statements
    with zipfile.ZipFile(tmp_path / "Frames-v3.zip") as zf:
        assert zf.namelist() == [name for _, name in frames]


def test_the_cameras_export_imports_into_a_fresh_database_as_it_left(db_session, settings, v3_tree, shared_dir,
                                                                    tmp_path, fresh_session_factory):
    """v3d's cameras export, as downloaded (no image: the sizes are in its ``cameras.json``), imports into an empty
    database as a SoccerNet-calibration set: one single-view system per view, named as in the export, at its image
    size, with its field lines (to the export's normalised precision) and a camera fitted to them (a camera the game's
    camera rig or the players gave a view with few lines may not be, a set having neither)."""
    import_soccernet_v3(db_session, v3_tree, settings)
    import_sn_calibration(db_session, write_calibration_zip(shared_dir, tmp_path / "wc" / "a.zip"), settings,
                          width=960, height=540)
    cams = export_cameras(db_session, tmp_path / "cameras", include_all=True)
    index = json.loads((tmp_path / "cameras" / "cameras.json").read_text())
    views = {v["name"]: (s["width"], s["height"], v["game"], v["frame"]) for s in index["sets"] for v in s["views"]}
    assert len(index["sets"]) == 2  # 1920x1080 and 960x540
    fresh = fresh_session_factory("fresh")
    report = import_sn_calibration(fresh, tmp_path / "cameras", settings)
    assert report.systems == len(views)
    stored = {f.system.name: f for f in fresh.scalars(sa.select(Frame))}
    assert sorted(stored) == sorted(views)
    frames = {(s.game.path, f.name): f for s in _systems(db_session).values() for f in s.frames}
    fitted = helped = 0
    for name, (w, h, game, frame_name) in views.items():
        back, source = stored[name], frames[(game, frame_name)]
        assert (back.width, back.height) == (w, h)
        lines, original = back.field_lines.lines, source.field_lines.lines
        assert sorted(lines) == sorted(original)
        for cls in original:  # every point of a class, pooled, as the export writes them
            ours = np.array([p for poly in original[cls] for p in poly])
            theirs = np.array([p for poly in lines[cls] for p in poly])
            assert np.allclose(np.sort(ours, axis=0), np.sort(theirs, axis=0), atol=1e-6)
        got = back.calibration is not None and back.calibration.camera is not None
        assisted = source.calibration is not None and bool(
            {"rig_assisted", "player_assisted"} & set(source.calibration.flags))
        alone = source.calibration is not None and source.calibration.admitted and not assisted
        assert got or not alone  # a view admitted from its own lines is fitted again from them
        fitted += got
        helped += assisted and source.calibration.camera is not None
    # the views the game's camera rig or their players helped may not calibrate alone: a single-view set has neither
    assert helped >= 1 and fitted >= cams.cameras - helped
