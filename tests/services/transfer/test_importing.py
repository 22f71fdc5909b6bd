"""Import: what lands in the database, idempotency, and bad input that stores nothing."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest
import sqlalchemy as sa

from app.core.errors import DatasetError
from app.db.models import (
    BallKind,
    CalibrationSource,
    CalibrationStatus,
    Frame,
    FrameRole,
    Game,
    ReviewStatus,
    System,
    SystemKind,
    TriangulationStatus,
)
from app.geometry.calibration.result import PLAYERS_FLAG, RIG_FLAG
from app.geometry.jac import jac_admitted
from app.services.calibration.admission import admission_jac
from app.services.transfer.importing import import_sn_calibration, import_soccernet_v3, read_sn_calibration
from app.services.wording.words import WORDS

from ..datasets import DEV_GAME, dev_game_dir, true_balls, write_calibration_zip, write_v3_game

pytestmark = pytest.mark.engine


def _counts(session) -> dict[str, int]:
    tables = ("games", "systems", "frames", "field_lines", "calibrations", "ball_labels", "triangulations",
              "triangulation_pairs", "ball_reprojections", "optimised_boxes", "review_decisions")
    return {t: session.execute(sa.text(f"SELECT count(*) FROM {t}")).scalar() for t in tables}


def _frame(session, system: str, frame: str) -> Frame:
    return session.scalars(sa.select(Frame).join(System).where(System.name == system, Frame.name == frame)).one()


def test_import_soccernet_v3_stores_systems_frames_labels_and_derived_rows(db_session, settings, v3_tree, shared_dir):
    report = import_soccernet_v3(db_session, v3_tree, settings)
    src = json.loads((dev_game_dir(shared_dir) / "Labels-v3.json").read_text())

    assert (report.games, report.systems, report.frames, report.systems_new) == (1, 3, 8, 3)
    assert report.calibrated + report.refused == 8
    # refusals are counted by the calibration's codes, each with its words (no sentence parsed back)
    assert sum(report.refusal_reasons.values()) == report.refused
    assert set(report.refusal_reasons) <= set(WORDS["refusal"]), report.refusal_reasons
    game = db_session.scalars(sa.select(Game)).one()
    assert (game.league, game.season, game.match) == DEV_GAME
    systems = {s.name: s for s in game.systems}
    assert set(systems) == {"0.png", "2.png", "3.png"}
    assert [f.name for f in systems["2.png"].frames] == ["2.png", "2_1.png", "2_2.png", "2_3.png"]
    assert [f.role for f in systems["2.png"].frames] == [FrameRole.ACTION] + [FrameRole.REPLAY] * 3
    assert all(s.kind is SystemKind.SOCCERNET_V3 and s.review.status is ReviewStatus.PENDING for s in game.systems)

    f = _frame(db_session, "0.png", "0_1.png")
    item = src["replays"]["0_1.png"]
    assert (f.width, f.height) == (item["imageMetadata"]["width"], item["imageMetadata"]["height"])
    assert f.image_root == str(v3_tree.resolve())
    assert f.image_zip.endswith("/Frames-v3.zip") and f.image_member == "0_1.png" and f.image_path is None
    assert not f.image_zip.startswith("/")  # relative to the dataset's folder
    with zipfile.ZipFile(Path(f.image_root) / f.image_zip) as zf:
        assert zf.read(f.image_member)[:8] == b"\x89PNG\r\n\x1a\n"
    ball = next(b["points"] for b in item["bboxes"] if b["class"] == "Ball")
    assert f.ball_label.kind is BallKind.BOX
    assert f.ball_label.box == [ball["x1"], ball["y1"], ball["x2"], ball["y2"]] == f.ball_label.original_box
    assert not f.ball_label.edited
    first = item["lines"][0]
    assert f.field_lines.lines[first["class"]][0] == np.reshape(first["points"], (-1, 2)).tolist()
    assert f.field_lines.original_lines == f.field_lines.lines

    # every frame was calibrated or refused with a reason; admission and pairs follow from them
    frames = [f for system in game.systems for f in system.frames]
    assert report.rig_assisted >= sum(RIG_FLAG in f.calibration.flags and PLAYERS_FLAG not in f.calibration.flags
                                      for f in frames)
    assert report.calibrated == sum(f.calibration.status is CalibrationStatus.CALIBRATED for f in frames)
    balls = true_balls(shared_dir)
    for system in game.systems:
        for frame in system.frames:
            cal = frame.calibration
            assert cal.source is CalibrationSource.COMPUTED
            if cal.status is CalibrationStatus.CALIBRATED:
                assert cal.camera is not None and 0.0 <= cal.jac_0005 <= cal.jac_001 <= cal.jac_002 <= 1.0
            else:
                assert cal.camera is None and cal.reason
            assert cal.admitted == (cal.status is CalibrationStatus.CALIBRATED
                                    and jac_admitted(admission_jac(cal, settings), settings.admit_jac_min))
        views = [f for f in system.frames if f.calibration.admitted and f.ball_label is not None]
        tri = system.triangulation
        assert len(tri.pairs) == len(views) * (len(views) - 1) // 2
        for pair in tri.pairs:
            paper = (pair.error_px is not None and pair.error_px < settings.triangulation_tau_px
                     and pair.baseline_m >= settings.min_baseline_m)
            # beyond the paper: a pair of weak calibrations, or one outweighed by a pair of sure ones, is left out
            assert pair.kept == (paper and pair.reason not in ("weak_calibrations", "outweighed"))
            assert pair.reason not in ("weak_calibrations", "outweighed") or paper
        if any(p.kept for p in tri.pairs):
            assert tri.status is TriangulationStatus.TRIANGULATED
            assert np.linalg.norm(np.subtract(tri.ball3d, balls[system.name])) < 1.0  # metres, vs the truth
            for frame in views:
                assert frame.optimised_box is not None and frame.optimised_box.d_opt_px > 0
        else:
            assert tri.ball3d is None and all(f.optimised_box is None for f in system.frames)


def test_import_twice_gives_the_same_rows(db_session, settings, v3_tree):
    import_soccernet_v3(db_session, v3_tree, settings)
    before = _counts(db_session)
    ids = db_session.execute(sa.select(Frame.id, Frame.name).order_by(Frame.id)).all()
    again = import_soccernet_v3(db_session, v3_tree, settings)
    assert (again.systems_new, again.systems_changed, again.calibrated, again.refused) == (0, 0, 0, 0)
    assert _counts(db_session) == before
    assert db_session.execute(sa.select(Frame.id, Frame.name).order_by(Frame.id)).all() == ids


def test_reimport_refreshes_originals_but_keeps_a_reviewers_edit(db_session, settings, shared_dir, tmp_path):
    from app.services.curation.editing import update_ball_label

    root = tmp_path / "v3"
    write_v3_game(shared_dir, root, actions=("0.png",))
    import_soccernet_v3(db_session, root, settings)
    f = _frame(db_session, "0.png", "0.png")
    update_ball_label(db_session, f.id, box=[600.0, 850.0, 622.0, 872.0], settings=settings)

    def move_ball(data):  # the dataset's own box changes, for both frames
        for item in (data["actions"]["0.png"], data["replays"]["0_1.png"]):
            for b in item["bboxes"]:
                if b["class"] == "Ball":
                    b["points"]["x1"] += 1
                    b["points"]["x2"] += 1

    write_v3_game(shared_dir, root, actions=("0.png",), edit=move_ball)
    report = import_soccernet_v3(db_session, root, settings)
    assert report.systems_changed == 1
    edited, replay = _frame(db_session, "0.png", "0.png"), _frame(db_session, "0.png", "0_1.png")
    assert edited.ball_label.box == [600.0, 850.0, 622.0, 872.0]  # the reviewer's box stays
    assert edited.ball_label.original_box[0] == 618.0  # 617 + 1: the original follows the file
    assert replay.ball_label.box == replay.ball_label.original_box  # unedited: follows the file


def test_an_overwrite_merge_replaces_an_edit_in_one_revertible_entry_per_system(db_session, settings, shared_dir,
                                                                                  tmp_path):
    """``overwrite``: the release's box replaces the reviewer's, in an entry of the system that a revert undoes; the
    system's accept of the reviewer's box goes back to pending."""
    from app.db.models import AuditEntry, ReviewStatus
    from app.services.curation.decisions import decide_review
    from app.services.curation.editing import update_ball_label
    from app.services.curation.reverting import revert_entry

    root = tmp_path / "v3"
    write_v3_game(shared_dir, root, actions=("0.png",))
    import_soccernet_v3(db_session, root, settings)
    f = _frame(db_session, "0.png", "0.png")
    original, system_id = list(f.ball_label.box), f.system_id
    update_ball_label(db_session, f.id, box=[600.0, 850.0, 622.0, 872.0], settings=settings, actor="ana")
    decide_review(db_session, system_id=system_id, status=ReviewStatus.ACCEPTED, actor="rita")
    kept = import_soccernet_v3(db_session, root, settings)  # keep-newer: a release is older than every edit
    assert (kept.systems_merged, kept.systems_changed) == (0, 0)
    report = import_soccernet_v3(db_session, root, settings, merge="overwrite", actor="adam")
    assert (report.systems_merged, report.decisions_reset, report.decisions_from_file) == (1, 1, 0)
    db_session.expire_all()
    system = db_session.get(System, system_id)
    assert _frame(db_session, "0.png", "0.png").ball_label.box == original
    assert system.review_status is ReviewStatus.PENDING and "changed its labels" in system.review.reset_reason
    entry = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.action == "system.import")).one()
    assert (entry.actor, entry.system_id, entry.frame_id) == ("adam", system_id, None)
    assert entry.summary.startswith("import of v3 changed ball of V1 moved ")
    assert "system set back to pending" in entry.summary
    revert_entry(db_session, entry.id, settings=settings, actor="rita")
    db_session.expire_all()
    assert _frame(db_session, "0.png", "0.png").ball_label.box == [600.0, 850.0, 622.0, 872.0]
    assert db_session.get(System, system_id).review_status is ReviewStatus.ACCEPTED


def _damage(path_field: str):
    """An ``edit`` for :func:`write_v3_game` and the text the error must contain."""
    def nan_box(d):
        d["actions"]["0.png"]["bboxes"][0]["points"]["x1"] = float("nan")

    def outside_box(d):
        d["actions"]["0.png"]["bboxes"][0]["points"].update(x1=2000, x2=2010)

    def implausible_box(d):
        d["actions"]["0.png"]["bboxes"][0]["points"].update(x1=0, y1=0, x2=1e308, y2=1e308)

    def unknown_class(d):
        d["replays"]["0_1.png"]["lines"][0]["class"] = "Penalty spot"

    def unknown_replay(d):
        d["actions"]["0.png"]["linked_replays"].append("0_9.png")

    def bad_size(d):
        d["actions"]["0.png"]["imageMetadata"]["width"] = 0

    return {
        "nan": (nan_box, "actions['0.png'].bboxes[0] (Ball)", "NaN"),
        "outside": (outside_box, "actions['0.png'].bboxes[0] (Ball)", "entirely outside the 1920x1080 image"),
        "implausible": (implausible_box, "actions['0.png'].bboxes[0] (Ball)", "no plausible ball label"),
        "class": (unknown_class, "lines[0]: unknown line class 'Penalty spot'", "replays['0_1.png']"),
        "replay": (unknown_replay, "actions['0.png'].linked_replays", "'0_9.png' is not in 'replays'"),
        "size": (bad_size, "actions['0.png'].imageMetadata.width", "integer > 1"),
    }[path_field]


@pytest.mark.parametrize("case", ["class", "replay", "size"])
def test_bad_labels_raise_naming_file_and_field_and_store_nothing(db_session, settings, shared_dir, tmp_path, case):
    edit, field, detail = _damage(case)
    root = tmp_path / "v3"
    write_v3_game(shared_dir, root, actions=("1.png",), game=("lg", "s1", "good game"))  # valid, read first
    write_v3_game(shared_dir, root, actions=("0.png",), edit=edit, game=("lg", "s1", "zz bad game"))
    with pytest.raises(DatasetError) as exc:
        import_soccernet_v3(db_session, root, settings)
    msg = str(exc.value)
    assert "zz bad game/Labels-v3.json" in msg and field in msg and detail in msg
    assert exc.value.file.endswith("Labels-v3.json")
    assert _counts(db_session)["games"] == 0 and _counts(db_session)["frames"] == 0


@pytest.mark.parametrize("case", ["nan", "outside", "implausible"])
def test_a_refused_ball_box_leaves_its_game_out_named_and_the_good_game_imports(db_session, settings, shared_dir,
                                                                               tmp_path, case):
    """A ball box the shared label check refuses (NaN, entirely outside the image, or beyond its plausible range:
    ``[0, 0, 1e308, 1e308]`` passed before and aborted the whole import in the 3D ball's computation, "SVD did not
    converge", naming no file and losing the good game beside it). The game holding it is left out, named by its
    labels file relative to the dataset, the entry and why; the good game is stored."""
    edit, field, detail = _damage(case)
    root = tmp_path / "v3"
    write_v3_game(shared_dir, root, actions=("1.png",), game=("lg", "s1", "good game"))
    write_v3_game(shared_dir, root, actions=("0.png",), edit=edit, game=("lg", "s1", "zz bad game"))
    report = import_soccernet_v3(db_session, root, settings)
    assert len(report.skipped_games) == 1, report.skipped_games
    skipped = report.skipped_games[0]
    assert skipped.startswith("lg/s1/zz bad game/Labels-v3.json: ") and field in skipped and detail in skipped
    assert str(tmp_path) not in skipped  # the dataset's own names, never a server path
    assert report.games == 1 and _counts(db_session)["games"] == 1
    assert db_session.scalars(sa.select(Game.match)).all() == ["good game"]


def test_truncated_json_is_refused(db_session, settings, shared_dir, tmp_path):
    game_dir = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",))
    labels = game_dir / "Labels-v3.json"
    labels.write_text(labels.read_text()[:500])
    with pytest.raises(DatasetError, match=r"Labels-v3.json: invalid or truncated JSON"):
        import_soccernet_v3(db_session, tmp_path / "v3", settings)
    assert _counts(db_session)["games"] == 0


@pytest.mark.parametrize("entry", ["../evil.png", "frames/../../evil.png", "/abs.png", "..\\win.png"])
def test_zip_entries_escaping_the_archive_are_refused(db_session, settings, shared_dir, tmp_path, entry):
    game_dir = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",))
    with zipfile.ZipFile(game_dir / "Frames-v3.zip", "a") as zf:
        zf.writestr(entry, b"x")
    with pytest.raises(DatasetError, match="unsafe entry name") as exc:
        import_soccernet_v3(db_session, tmp_path / "v3", settings)
    assert repr(entry) in str(exc.value) and "Frames-v3.zip" in str(exc.value)
    assert _counts(db_session)["games"] == 0
    assert not (tmp_path / "evil.png").exists() and not (tmp_path / "v3" / "evil.png").exists()


def test_a_folder_of_frames_is_used_when_there_is_no_zip(db_session, settings, shared_dir, tmp_path):
    game_dir = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), with_images=False)
    (game_dir / "Frames-v3").mkdir()
    ok, png = cv2.imencode(".png", np.zeros((54, 96), np.uint8))
    (game_dir / "Frames-v3" / "0.png").write_bytes(png.tobytes())
    import_soccernet_v3(db_session, tmp_path / "v3", settings)
    action, replay = _frame(db_session, "0.png", "0.png"), _frame(db_session, "0.png", "0_1.png")
    assert action.image_root == str((tmp_path / "v3").resolve()) and action.image_zip is None
    assert Path(action.image_root) / action.image_path == (game_dir / "Frames-v3" / "0.png").resolve()
    assert (replay.image_path, replay.image_zip) == (None, None)  # no image anywhere: none stored


def test_missing_path_is_a_dataset_error(db_session, settings, tmp_path):
    with pytest.raises(DatasetError, match="no such file or folder"):
        import_soccernet_v3(db_session, tmp_path / "nowhere", settings)
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="no Labels-v3.json found"):
        import_soccernet_v3(db_session, tmp_path / "empty", settings)


# ----- SoccerNet-calibration ----------------------------------------------------------------------
def test_import_sn_calibration_zip_makes_single_view_systems(db_session, settings, shared_dir, tmp_path):
    archive = write_calibration_zip(shared_dir, tmp_path / "wc" / "annotations.zip", extra={"match_info.json": b"{}"})
    report = import_sn_calibration(db_session, archive, settings, width=960, height=540)
    assert (report.systems, report.frames) == (3, 3)
    game = db_session.scalars(sa.select(Game)).one()
    assert (game.league, game.season, game.match) == ("sn-calibration", "wc", "annotations")
    assert [s.name for s in game.systems] == ["1", "2", "3"]
    with zipfile.ZipFile(shared_dir / "data/real/wc14-test/annotations.zip") as zf:
        raw = json.loads(zf.read("1.json"))
    frame = game.systems[0].frames[0]
    assert (frame.name, frame.role, frame.width, frame.height) == ("1.json", FrameRole.CAMERA, 960, 540)
    cls, pts = next(iter(raw.items()))
    got = frame.field_lines.lines[cls][0]
    assert got[0] == pytest.approx([pts[0]["x"] * 959, pts[0]["y"] * 539])  # x (W - 1), y (H - 1)
    assert frame.ball_label is None and game.systems[0].kind is SystemKind.SINGLE_VIEW
    assert all(s.triangulation.status is TriangulationStatus.INSUFFICIENT_VIEWS for s in game.systems)
    assert report.calibrated >= 2  # real broadcast frames with many lines


def test_sn_calibration_size_from_images_beside_the_json(shared_dir, tmp_path):
    import cv2

    folder = tmp_path / "calib"
    folder.mkdir()
    with zipfile.ZipFile(shared_dir / "data/real/wc14-test/annotations.zip") as zf:
        (folder / "7.json").write_bytes(zf.read("7.json"))
        (folder / "8.json").write_bytes(zf.read("8.json"))
    cv2.imwrite(str(folder / "7.jpg"), np.zeros((270, 480, 3), np.uint8))
    with pytest.raises(DatasetError, match=r"8.json: image size unknown"):
        read_sn_calibration(folder)
    (folder / "8.json").unlink()
    game = read_sn_calibration(folder)
    frame = game.systems[0].frames[0]
    assert (frame.width, frame.height, frame.image_root, frame.image_path) == (480, 270, str(folder.resolve()), "7.jpg")


def test_sn_calibration_errors_name_the_member(db_session, settings, shared_dir, tmp_path):
    bad = write_calibration_zip(shared_dir, tmp_path / "bad.zip", names=("1.json",),
                                extra={"2.json": b'{"Side line top": [{"x": 0.1, "y": '})
    with pytest.raises(DatasetError, match=r"bad.zip!2.json: invalid or truncated JSON"):
        import_sn_calibration(db_session, bad, settings, width=960, height=540)
    unknown = write_calibration_zip(shared_dir, tmp_path / "unknown.zip", names=("1.json",),
                                    extra={"2.json": b'{"Penalty spot": [{"x": 0.1, "y": 0.2}]}'})
    with pytest.raises(DatasetError, match=r"unknown.zip!2.json: field lines: unknown line class 'Penalty spot'"):
        import_sn_calibration(db_session, unknown, settings, width=960, height=540)
    nan = write_calibration_zip(shared_dir, tmp_path / "nan.zip", names=("1.json",),
                                extra={"2.json": b'{"Middle line": [{"x": NaN, "y": 0.2}]}'})
    with pytest.raises(DatasetError, match=r"nan.zip!2.json: .*'Middle line'.*NaN"):
        import_sn_calibration(db_session, nan, settings, width=960, height=540)
    assert _counts(db_session)["games"] == 0


def test_batches_of_games_store_the_same_rows_as_one_batch(shared_dir, fresh_session_factory):
    """An import is stored in transactions of whole games (bounded memory at SoccerNet size); one game
    per batch, sharing one calibration pool (the second game's first pass calibrating while the first
    is stored), gives exactly what a single batch gives, and what calibrating in this process gives."""
    import sqlalchemy as sa

    from app.core.config import Settings
    from app.db.models import Calibration, Doubt, Frame, System
    dev = shared_dir / "data" / "synthetic" / "soccernet-v3-dev"

    def snapshot(session):
        cals = session.execute(sa.select(Frame.name, Calibration.status, Calibration.jac_0005, Calibration.flags,
                                         Calibration.camera)
                               .join(Calibration, Calibration.frame_id == Frame.id).order_by(Frame.name)).all()
        systems = session.execute(sa.select(System.name, System.worst_error_px, System.label_doubts)
                                  .order_by(System.name)).all()
        return cals, systems, session.scalar(sa.select(sa.func.count(Doubt.id)))

    one = fresh_session_factory("one")
    report_one = import_soccernet_v3(one, dev, Settings(calibration_workers=2))
    many = fresh_session_factory("many")
    seen: list[tuple[str, int, int]] = []
    report_many = import_soccernet_v3(many, dev, Settings(calibration_workers=2, import_batch_frames=1),
                                      progress=lambda stage, done, total: seen.append((stage, done, total)))
    assert [s for s in seen if s[0] == "games"] == [("games", 1, 2), ("games", 2, 2)]
    assert [s for s in seen if s[0] != "games"] == [("read", 0, 2), ("read", 1, 2)]  # reading first, from game 0
    assert (report_many.frames, report_many.calibrated, report_many.refused, report_many.triangulated,
            report_many.rig_assisted) == (report_one.frames, report_one.calibrated, report_one.refused,
                                          report_one.triangulated, report_one.rig_assisted)
    assert len(report_many.calibration_ms) == len(report_one.calibration_ms)
    assert snapshot(many) == snapshot(one)
    alone = fresh_session_factory("alone")
    import_soccernet_v3(alone, dev, Settings(calibration_workers=1))
    assert snapshot(alone) == snapshot(one)


def test_an_import_reads_its_first_batch_once_the_others_twice_and_holds_two_batches_at_most(shared_dir,
                                                                                             fresh_session_factory,
                                                                                             monkeypatch):
    """Validation reads every game and drops it but the first batch's, which is stored as read (a labels file costs
    one parse, a flood of boxes its parse once); each other batch is read again when its calibration starts, so
    memory holds the records of two batches at most, not the whole input (400 games at SoccerNet size)."""
    import gc
    import weakref

    from app.core.config import Settings
    from app.services.transfer import importing

    dev = shared_dir / "data" / "synthetic" / "soccernet-v3-dev"
    alive: list[weakref.ref] = []
    reads: list[str] = []
    alive_at_read: list[int] = []
    real = importing.read_soccernet_v3_game

    def read(labels, *args, **limits):
        gc.collect()
        alive_at_read.append(sum(ref() is not None for ref in alive))
        rec = real(labels, *args, **limits)
        alive.append(weakref.ref(rec))
        reads.append(rec.match)
        return rec

    monkeypatch.setattr(importing, "read_soccernet_v3_game", read)
    report = import_soccernet_v3(fresh_session_factory("twice"), dev,
                                 Settings(calibration_workers=1, import_batch_frames=1))
    games = sorted(set(reads))
    assert report.games == len(games) == 2 and reads == games + games[1:]  # validation, then the later batch
    # The validation holds the first batch alone; the second game is read again while the first is being stored.
    assert alive_at_read == [0, 1, 1]


def test_an_import_collects_its_garbage_once_per_batch_and_puts_the_thresholds_back(shared_dir, fresh_session_factory,
                                                                                    monkeypatch):
    """While an import stores its batches the collector makes no full collection of its own (the batch's objects
    are held for the whole batch: each one traversed them all); the import collects once per batch, and the
    thresholds are put back when the last import of the process ends, also after a failure."""
    import gc

    from app.core.config import Settings
    from app.services.transfer import importing

    dev = shared_dir / "data" / "synthetic" / "soccernet-v3-dev"
    before = gc.get_threshold()
    during: list[tuple[int, int, int]] = []
    collected: list[int] = []
    real_collect = gc.collect
    real_store = importing._store

    def store(*args, **kwargs):
        during.append(gc.get_threshold())
        return real_store(*args, **kwargs)

    def collect(*args):
        collected.append(len(during))
        return real_collect(*args)

    monkeypatch.setattr(importing, "_store", store)
    monkeypatch.setattr(importing.gc, "collect", collect)
    import_soccernet_v3(fresh_session_factory("gc"), dev, Settings(calibration_workers=1, import_batch_frames=1))
    assert during == [(before[0], before[1], importing._NO_AUTOMATIC_FULL_COLLECTION)] * 2
    assert collected == [1, 2]  # once after each batch
    assert gc.get_threshold() == before
    with pytest.raises(RuntimeError), importing._full_collections_by_batch():
        with importing._full_collections_by_batch():  # two imports at once: the first to end leaves them
            assert gc.get_threshold()[2] == importing._NO_AUTOMATIC_FULL_COLLECTION
        assert gc.get_threshold()[2] == importing._NO_AUTOMATIC_FULL_COLLECTION
        raise RuntimeError("an import that fails")
    assert gc.get_threshold() == before


def test_the_player_boxes_are_stored_as_they_came_and_an_import_again_changes_none(db_session, settings, v3_tree,
                                                                                   shared_dir):
    import_soccernet_v3(db_session, v3_tree, settings)
    src = json.loads((dev_game_dir(shared_dir) / "Labels-v3.json").read_text())
    items = {**src["actions"], **src["replays"]}
    frames = db_session.scalars(sa.select(Frame)).all()
    assert frames
    for f in frames:
        want = [(b["class"], None if b["ID"] is None else str(b["ID"]),
                 (b["points"]["x1"], b["points"]["y1"], b["points"]["x2"], b["points"]["y2"]))
                for b in items[f.name]["bboxes"] if b["class"] != "Ball"]
        assert [(p.cls, p.ident, (p.x1, p.y1, p.x2, p.y2)) for p in f.players] == want
    n = db_session.execute(sa.text("SELECT count(*) FROM player_boxes")).scalar()
    assert n == sum(len([b for b in it["bboxes"] if b["class"] != "Ball"]) for name, it in items.items()
                    if name in {f.name for f in frames})
    ids = db_session.execute(sa.text("SELECT id FROM player_boxes ORDER BY id")).scalars().all()
    import_soccernet_v3(db_session, v3_tree, settings)
    assert db_session.execute(sa.text("SELECT id FROM player_boxes ORDER BY id")).scalars().all() == ids
