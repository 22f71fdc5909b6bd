"""ISSIA sequences through the service (``app.services.issia.sequences``): import in both modes, idempotent
re-import, edits that re-fit the trajectory in their transaction, the ISSIA-3D export round trip, and
the issue's figures on the whole dev sequence read back from the stored rows."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import StaleVersionError
from app.datasets.issia3d import read_issia3d_csv
from app.db.models import (
    BallKind,
    CalibrationSource,
    CalibrationStatus,
    Doubt,
    Frame,
    FrameRole,
    Game,
    ReviewStatus,
    System,
    SystemKind,
    TrajectoryPoint,
)
from app.geometry.calibration.result import REFUSAL_CODES
from app.geometry.camera import Camera
from app.services.curation.decisions import decide_review
from app.services.curation.editing import set_view_excluded, update_ball_label
from app.services.issia import sequences as issia_service
from app.services.issia.cameras import STATIC_CAMERA_REFUSALS
from app.services.issia.export import export_issia3d
from app.services.issia.sequences import import_issia
from tests.conftest import migrate_new_database
from tests.services.issia_data import dev_dir, dev_truth, write_issia_stretch


@pytest.fixture
def stretch(shared_dir, tmp_path):
    """Frames 0..39 of the dev sequence (the outlier label of cam4 at frame 13 included)."""
    return write_issia_stretch(shared_dir, tmp_path / "issia-dev")


def _systems(session) -> dict[int, System]:
    return {s.frame_index: s for s in session.scalars(sa.select(System).where(System.kind == SystemKind.ISSIA))}


def _view(system: System, name: str) -> Frame:
    return next(f for f in system.frames if f.name == name)


def test_import_from_calibration_json_stores_the_sequence(db_session, db_settings, stretch, shared_dir):
    report = import_issia(db_session, stretch, db_settings)
    assert (report.games, report.systems, report.frames, report.systems_new) == (1, 40, 240, 40)
    assert report.calibrated == 6 and report.refused == 0
    game = db_session.scalars(sa.select(Game)).one()
    assert (game.league, game.season, game.match) == ("issia", "sequences", "issia-dev")
    systems = _systems(db_session)
    assert sorted(systems) == list(range(40))
    given = json.loads((stretch / "issia_calibration.json").read_text())
    truth = {fr["frame"]: fr for fr in dev_truth(shared_dir)["frames"]}
    rows = {int(r["frame"]): r for r in csv.DictReader((stretch / "ball_points.csv").open())}
    s13 = systems[13]
    assert [f.name for f in s13.frames] == [f"cam{k}" for k in range(1, 7)]
    assert {f.role for f in s13.frames} == {FrameRole.STATIC}
    for f in s13.frames:
        cal = f.calibration
        assert cal.source is CalibrationSource.IMPORTED and cal.admitted
        np.testing.assert_allclose(Camera.from_soccernet(cal.camera).projection_matrix,
                                   Camera.from_soccernet(given[f.name[3:]]).projection_matrix,
                                   rtol=1e-9, atol=1e-9)
        x = rows[13][f"x_{f.name}"]
        if x:
            assert f.ball_label.kind is BallKind.POINT
            assert f.ball_label.point == [float(x), float(rows[13][f"y_{f.name}"])]
        else:
            assert f.ball_label is None
        assert f.media_frame == 13 and f.image_path == f"videos/{f.name}.mp4" and f.image_root.startswith("/")
    # the wrong label of cam4 at frame 13 breaks the trajectory: flagged, left out, a doubt with its fix
    tp = s13.trajectory_point
    cam4 = _view(s13, "cam4")
    assert tp.flagged == [cam4.id] and cam4.id not in tp.cam_list
    assert tp.residuals_px[str(cam4.id)] > 15
    doubt = next(d for d in s13.doubts if d.kind == "ball_off_consensus")
    assert doubt.frame_id == cam4.id and doubt.accuses_label
    assert doubt.evidence["residual_px_1920"] == pytest.approx(tp.residuals_px[str(cam4.id)])
    assert doubt.evidence["fitted_position_m"] == tp.ball3d_smoothed
    assert doubt.suggestion["action"] in ("snap_point", "exclude_view")
    # one label left: no ball_3D of its own, the trajectory's position is "fitted"
    assert tp.ball3d is None and s13.triangulation.ball3d is None and tp.source == "fitted"
    assert np.linalg.norm(np.asarray(tp.ball3d_smoothed) - truth[13]["ball_3d"]) < 0.1
    # elsewhere the stored triangulation is the frame's own (the kept labels), right, with optimised boxes
    for i, s in systems.items():
        tp = s.trajectory_point
        if tp.ball3d is None:
            continue
        np.testing.assert_allclose(s.triangulation.ball3d, tp.ball3d, atol=1e-9)
        assert np.linalg.norm(np.asarray(tp.ball3d) - truth[i]["ball_3d"]) < 0.3
        for f in s.frames:
            if f.id in tp.cam_list:
                assert f.optimised_box is not None and f.optimised_box.d_opt_px > 0
    errors = [np.linalg.norm(np.asarray(s.trajectory_point.ball3d_smoothed) - truth[i]["ball_3d"])
              for i, s in systems.items() if s.trajectory_point.ball3d_smoothed is not None]
    assert len(errors) >= 38 and np.median(errors) < 0.05


def test_a_camera_absent_from_the_calibration_file_is_refused_with_its_code(db_session, db_settings, stretch):
    """A camera ``issia_calibration.json`` does not give is stored refused, its reason the words table's sentence,
    and the import counts it by its code."""
    path = stretch / "issia_calibration.json"
    data = json.loads(path.read_text())
    del data["3"]
    path.write_text(json.dumps(data))
    report = import_issia(db_session, stretch, db_settings)
    assert (report.calibrated, report.refused) == (5, 1)
    assert report.refusal_reasons == {"not_in_calibration_json": report.refused}
    reasons = {f.calibration.reason for s in _systems(db_session).values() for f in s.frames
               if f.calibration.status == CalibrationStatus.REFUSED}
    assert reasons == {"not in issia_calibration.json"}


def test_import_from_lines_calibrates_each_camera_once(db_session, db_settings, stretch, shared_dir):
    report = import_issia(db_session, stretch, db_settings, from_lines=True)
    assert report.calibrated + report.refused == 6 and report.calibrated >= 4
    assert sum(report.refusal_reasons.values()) == report.refused
    assert set(report.refusal_reasons) <= {*REFUSAL_CODES, *STATIC_CAMERA_REFUSALS}, report.refusal_reasons
    systems = _systems(db_session)
    for view in systems[0].frames:
        cams = {json.dumps(_view(s, view.name).calibration.camera, sort_keys=True) for s in systems.values()}
        assert len(cams) == 1  # one camera per static camera, on every view
        assert view.calibration.source is CalibrationSource.COMPUTED
        assert view.calibration.admitted == (view.calibration.camera is not None)
        if view.calibration.admitted:
            assert view.calibration.jac_0005 > 0.75
            assert "ball_bundle" in view.calibration.flags  # refined with the others from lines and ball
    truth = {fr["frame"]: fr for fr in dev_truth(shared_dir)["frames"]}
    errors = [np.linalg.norm(np.asarray(s.trajectory_point.ball3d_smoothed) - truth[i]["ball_3d"])
              for i, s in systems.items() if s.trajectory_point.ball3d_smoothed is not None]
    assert len(errors) >= 38 and np.median(errors) < 0.1


def test_reimport_is_idempotent_and_keeps_edits(db_session, db_settings, stretch):
    import_issia(db_session, stretch, db_settings)
    s20 = _systems(db_session)[20]
    cam3 = _view(s20, "cam3")
    moved = [cam3.ball_label.point[0] + 2.0, cam3.ball_label.point[1]]
    update_ball_label(db_session, cam3.id, point=moved, settings=db_settings)
    counts = {t: db_session.scalar(sa.select(sa.func.count()).select_from(t)) for t in
              (System.__table__, Frame.__table__, TrajectoryPoint.__table__)}
    ids = sorted(db_session.scalars(sa.select(Frame.id)))
    report = import_issia(db_session, stretch, db_settings)
    assert (report.systems_new, report.systems_changed) == (0, 0)
    assert {t: db_session.scalar(sa.select(sa.func.count()).select_from(t)) for t in counts} == counts
    assert sorted(db_session.scalars(sa.select(Frame.id))) == ids
    db_session.expire_all()
    assert db_session.get(Frame, cam3.id).ball_label.point == moved


def test_an_overwrite_merge_puts_the_files_point_back_in_a_revertible_entry(db_session, db_settings, stretch):
    from app.db.models import AuditEntry
    from app.services.curation.reverting import revert_entry

    import_issia(db_session, stretch, db_settings)
    cam3 = _view(_systems(db_session)[20], "cam3")
    point = list(cam3.ball_label.point)
    moved = [point[0] + 2.0, point[1]]
    update_ball_label(db_session, cam3.id, point=moved, settings=db_settings)
    report = import_issia(db_session, stretch, db_settings, merge="overwrite")
    assert report.systems_merged >= 1
    db_session.expire_all()
    assert db_session.get(Frame, cam3.id).ball_label.point == point
    entry = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.action == "system.import",
                                                           AuditEntry.system_id == cam3.system_id)).one()
    assert "ball of V3 moved 2.0 px" in entry.summary
    revert_entry(db_session, entry.id, settings=db_settings)
    db_session.expire_all()
    assert db_session.get(Frame, cam3.id).ball_label.point == moved


def test_an_edit_refits_the_trajectory_and_its_doubts_in_one_transaction(db_session, db_settings, stretch):
    import_issia(db_session, stretch, db_settings)
    s20 = _systems(db_session)[20]
    cam3 = _view(s20, "cam3")
    x, y = cam3.ball_label.point
    update_ball_label(db_session, cam3.id, point=[x + 80.0, y], settings=db_settings)
    db_session.expire_all()
    s20 = db_session.get(System, s20.id)
    assert s20.trajectory_point.flagged == [cam3.id]
    doubt = db_session.scalars(sa.select(Doubt).where(Doubt.system_id == s20.id,
                                                      Doubt.kind == "ball_off_consensus")).one()
    assert doubt.frame_id == cam3.id and doubt.evidence["residual_px_1920"] > 60
    assert s20.label_doubts >= 1 and s20.doubt_counts["ball_off_consensus"] == 1
    # the fix: snap the point to where the trajectory projects -> the doubt goes, the label is kept
    assert doubt.suggestion["action"] == "snap_point"
    px, py = doubt.suggestion["point"]
    assert abs(px - x) < 5 and abs(py - y) < 5
    update_ball_label(db_session, cam3.id, point=doubt.suggestion["point"], settings=db_settings)
    db_session.expire_all()
    s20 = db_session.get(System, s20.id)
    assert s20.trajectory_point.flagged == [] and cam3.id in s20.trajectory_point.cam_list
    assert "ball_off_consensus" not in s20.doubt_counts
    # excluding the flagged view of frame 13 takes it out of the frame's labels; no doubt accuses it
    s13 = _systems(db_session)[13]
    cam4 = _view(s13, "cam4")
    set_view_excluded(db_session, cam4.id, True, settings=db_settings)
    db_session.expire_all()
    s13 = db_session.get(System, s13.id)
    assert cam4.id not in s13.trajectory_point.cam_list and s13.trajectory_point.flagged == []


def test_a_failing_refit_stores_nothing(db_session, db_settings, stretch, monkeypatch):
    import_issia(db_session, stretch, db_settings)
    s20 = _systems(db_session)[20]
    cam3 = _view(s20, "cam3")
    before = (list(cam3.ball_label.point), s20.trajectory_point.ball3d_smoothed, list(s20.trajectory_point.flagged))

    def broken(*args, **kwargs):
        raise RuntimeError("re-fit failed")

    monkeypatch.setattr(issia_service, "refit_sequence", broken)
    with pytest.raises(RuntimeError):
        update_ball_label(db_session, cam3.id, point=[before[0][0] + 80.0, before[0][1]], settings=db_settings)
    db_session.expire_all()
    s20 = db_session.get(System, s20.id)
    cam3 = db_session.get(Frame, cam3.id)
    assert (cam3.ball_label.point, s20.trajectory_point.ball3d_smoothed, s20.trajectory_point.flagged) == before
    assert "ball_off_consensus" not in s20.doubt_counts


def test_issia3d_export_round_trip(db_session, db_settings, stretch, tmp_path):
    import_issia(db_session, stretch, db_settings)
    systems = _systems(db_session)
    for i in (3, 13, 14):
        decide_review(db_session, system_id=systems[i].id, status=ReviewStatus.ACCEPTED)
    report = export_issia3d(db_session, tmp_path / "out")
    assert (report.sequences, report.rows) == (1, 3)
    split = json.loads((tmp_path / "out" / "issia-dev" / "split.json").read_text())
    assert (split["train"], split["test"]) == ([3, 4, 5, 6], [1, 2])
    report = export_issia3d(db_session, tmp_path / "all", include_all=True)
    rows = {r.frame: r for r in read_issia3d_csv(report.csv_paths[0])}
    assert sorted(rows) == list(range(40))
    db_session.expire_all()
    for i, s in _systems(db_session).items():
        r, tp = rows[i], s.trajectory_point
        assert r.ball_3d == (tuple(tp.ball3d) if tp.ball3d is not None else None)
        assert r.ball_3d_smoothed == (tuple(tp.ball3d_smoothed) if tp.ball3d_smoothed is not None else None)
        assert r.ball_3d_source == tp.source
        names = {f.id: f.name for f in s.frames}
        assert r.cam_list == tuple(sorted(int(names[fid][3:]) for fid in tp.cam_list))
        for f in s.frames:
            x, y = r.per_camera[int(f.name[3:])][:2]
            assert ([x, y] if x is not None else None) == (f.ball_label.point if f.ball_label else None)
        assert r.num_cameras == sum(f.ball_label is not None for f in s.frames)


@pytest.mark.parametrize("from_lines", [False, True], ids=["calibration_json", "lines"])
def test_issue_figures_through_the_service(db_session, db_settings, shared_dir, from_lines):
    """Issue 9's done-when figures on the whole dev sequence, from the stored rows."""
    from benchmarks.issia_service import service_figures

    import_issia(db_session, dev_dir(shared_dir), db_settings, from_lines=from_lines)
    game = db_session.scalars(sa.select(Game)).one()
    f = service_figures(db_session, game.id, dev_truth(shared_dir))
    assert f["ball_3D_coverage"] >= 0.95 and f["ball_3D_median_error_m"] <= 0.06
    assert f["smoothed_coverage"] >= 0.98 and f["smoothed_median_error_m"] <= 0.045
    assert f["outlier_labels"] >= 1 and f["outliers_in_cam_list"] == 0
    assert f["correct_kept_share"] >= 0.97


def _stored_trajectory(session) -> dict[int, tuple]:
    session.expire_all()
    return {i: (s.trajectory_point.ball3d_smoothed, s.trajectory_point.source, s.trajectory_point.flagged,
                s.trajectory_point.cam_list, s.trajectory_point.ball3d)
            for i, s in _systems(session).items()}


@pytest.mark.parametrize("edit, frame", [("moved", 70), ("removed", 70), ("excluded", 70), ("moved", 115)])
def test_an_edits_incremental_refit_equals_a_fit_from_scratch(db_session, db_settings, shared_dir, tmp_path,
                                                               monkeypatch, edit, frame):
    """The re-fit of an edit (only the stretch it touches read, re-fitted and written) stores the same
    trajectory as fitting the edited sequence again from scratch: positions within 1 mm, the same
    sources, flagged labels, kept labels and per-frame triangulations. On frames 0-119 of the dev
    sequence (pieces 0-23, 24-114, 115-119): frame 70 lies well inside a piece (that piece alone is
    re-fitted), frame 115 at a break (the pieces around it are segmented again)."""
    from app.services.issia import refit as issia_refit
    from app.services.issia.trajectory import fit_sequence

    import_issia(db_session, write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 119, videos=False), db_settings)
    view = next(f for f in _systems(db_session)[frame].frames if f.ball_label is not None)
    x, y = view.ball_label.point

    def whole_fit(*args, **kwargs):
        raise AssertionError("the edit re-fitted the whole sequence")

    monkeypatch.setattr(issia_refit, "fit_sequence", whole_fit)
    if edit == "moved":
        update_ball_label(db_session, view.id, point=[x + 4.0, y - 3.0], settings=db_settings)
    elif edit == "removed":
        update_ball_label(db_session, view.id, settings=db_settings)
    else:
        set_view_excluded(db_session, view.id, True, settings=db_settings)
    monkeypatch.undo()
    incremental = _stored_trajectory(db_session)
    game = db_session.scalars(sa.select(Game)).one()
    fit_sequence(db_session, game.id, db_settings)
    db_session.flush()
    scratch = _stored_trajectory(db_session)
    assert incremental.keys() == scratch.keys()
    for i in scratch:
        (p1, s1, f1, c1, b1), (p2, s2, f2, c2, b2) = incremental[i], scratch[i]
        assert (s1, f1, c1) == (s2, f2, c2), f"frame {i}"
        assert (p1 is None) == (p2 is None) and (b1 is None) == (b2 is None), f"frame {i}"
        if p1 is not None:
            assert np.linalg.norm(np.subtract(p1, p2)) < 1e-3, f"frame {i}"
        if b1 is not None:
            np.testing.assert_allclose(b1, b2, atol=1e-9)
    s = _systems(db_session)[frame]
    if edit != "moved":
        assert view.id not in s.trajectory_point.cam_list and str(view.id) not in s.trajectory_point.residuals_px
    # the system's own triangulation, recomputed once after the re-fit, is the stored ball_3D
    if s.trajectory_point.ball3d is not None:
        np.testing.assert_allclose(s.triangulation.ball3d, s.trajectory_point.ball3d, atol=1e-9)


def test_a_field_line_edit_refits_the_whole_sequence_only_when_its_view_gives_the_camera(db_session, db_settings,
                                                                                        stretch):
    """The sequence uses each camera's first admitted view's camera for every frame: new field lines of a
    later view leave the trajectory as it was; new field lines of that first view change the camera of
    every frame, and the stored trajectory is then the fit from scratch with the new camera."""
    from app.services.curation.editing import replace_field_lines
    from app.services.issia.trajectory import fit_sequence

    import_issia(db_session, stretch, db_settings)
    game = db_session.scalars(sa.select(Game)).one()
    before = _stored_trajectory(db_session)
    later = _view(_systems(db_session)[20], "cam3")
    shifted = {c: [[[x + 2.0, y] for x, y in poly] for poly in polys] for c, polys in later.field_lines.lines.items()}
    replace_field_lines(db_session, later.id, shifted, settings=db_settings)
    assert _stored_trajectory(db_session) == before
    assert db_session.get(Frame, later.id).calibration.source is CalibrationSource.COMPUTED
    first = _view(_systems(db_session)[0], "cam3")
    lines = first.field_lines.lines
    replace_field_lines(db_session, first.id, {c: [[[x + 2.0, y] for x, y in poly] for poly in polys]
                                               for c, polys in lines.items()}, settings=db_settings)
    after = _stored_trajectory(db_session)
    assert after != before  # cam3's camera is now the one its first view's lines give
    assert fit_sequence(db_session, game.id, db_settings) == []  # stored = the fit from scratch


def test_a_line_edit_of_a_camera_refined_with_the_ball_refines_it_again(db_session, db_settings, stretch):
    """Imported ``--from-lines``, every camera is refined with the ball's labels (flag ``ball_bundle``). A field-line
    edit of the view giving cam3 its camera, which gives back the same lines, refines the new camera from its lines
    with the ball's labels again: the camera comes back to the imported one (the lines alone put it elsewhere), with
    the flag, and the stored trajectory is the fit from scratch with it."""
    from app.services.calibration.calibrating import calibrate_lines
    from app.services.curation.editing import replace_field_lines
    from app.services.issia.trajectory import fit_sequence

    import_issia(db_session, stretch, db_settings, from_lines=True)
    game = db_session.scalars(sa.select(Game)).one()
    first = _view(_systems(db_session)[0], "cam3")
    imported = Camera.from_soccernet(first.calibration.camera)
    assert "ball_bundle" in first.calibration.flags
    lines = first.field_lines.lines
    alone = Camera.from_soccernet(calibrate_lines(lines, first.width, first.height, None).camera)
    taught = np.linalg.norm(alone.C - imported.C)
    assert taught > 0.005  # what the ball taught the camera
    shifted = {c: [[[x + 2.0, y] for x, y in poly] for poly in polys] for c, polys in lines.items()}
    replace_field_lines(db_session, first.id, shifted, settings=db_settings)
    replace_field_lines(db_session, first.id, lines, settings=db_settings)
    cal = db_session.get(Frame, first.id).calibration
    assert "ball_bundle" in cal.flags and cal.jac_0005 > 0.75
    again = Camera.from_soccernet(cal.camera)
    assert np.linalg.norm(again.C - imported.C) < 0.25 * taught
    assert fit_sequence(db_session, game.id, db_settings) == []  # stored = the fit from scratch


def test_an_edit_replaces_the_moved_trajectory_doubts_as_a_full_judgement_would(db_session, db_settings, stretch,
                                                                                 monkeypatch):
    """An edit in the piece of frame 13 (cam4's wrong label) moves frame 13 on the trajectory without changing
    its labels: its trajectory doubt is replaced from the new stored point without loading the system, and is
    what judging the whole system again stores (same doubts, order, counts; the evidence's new position)."""
    from app.services.derivation.doubts import update_doubts
    from app.services.issia import refit as issia_refit

    import_issia(db_session, stretch, db_settings)
    s13 = _systems(db_session)[13]
    before = s13.trajectory_point.ball3d_smoothed
    loaded = []
    real = issia_refit.load_for_recompute
    monkeypatch.setattr(issia_refit, "load_for_recompute", lambda session, ids, **options:
                        loaded.extend(ids) or real(session, ids, **options))
    view = next(f for f in _systems(db_session)[18].frames if f.ball_label is not None)
    update_ball_label(db_session, view.id, point=[view.ball_label.point[0] + 4.0, view.ball_label.point[1]],
                      settings=db_settings)
    assert s13.id not in loaded

    def stored(system_id):
        db_session.expire_all()
        s = db_session.get(System, system_id)
        return (s.trajectory_point.ball3d_smoothed, dict(s.doubt_counts), s.label_doubts,
                [(d.kind, d.frame_id, d.accuses_label, d.message, d.evidence, d.suggestion) for d in s.doubts])

    light = stored(s13.id)
    assert light[0] != before
    boc = [d for d in light[3] if d[0] == "ball_off_consensus"]
    assert len(boc) == 1 and boc[0][4]["fitted_position_m"] == light[0]
    update_doubts(db_session.get(System, s13.id), db_settings)
    db_session.flush()
    assert stored(s13.id) == light


def test_the_pieces_an_edit_reads_are_those_within_reach(db_session, db_settings, shared_dir, tmp_path):
    """``_pieces_around`` reads the stored pieces of a window of frames around the edit, widened until it holds
    every piece within ``REFIT_REACH`` of the one the edit touches: the same pieces the whole list gives."""
    from app.geometry.trajectory import REFIT_REACH
    from app.services.issia.refit import _pieces_around
    from app.services.issia.trajectory import piece_from_json

    import_issia(db_session, write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 199, videos=False), db_settings)
    game = db_session.scalars(sa.select(Game)).one()
    every = sorted({(p.first_frame, p.last_frame): p for p in (
        piece_from_json(d) for d in db_session.scalars(sa.select(TrajectoryPoint.piece)) if d)}.values(),
        key=lambda p: p.first_frame)
    assert len(every) > REFIT_REACH + 1
    gaps = [p.last_frame + 1 for p, q in zip(every, every[1:], strict=False) if q.first_frame > p.last_frame + 1]
    assert gaps, "the dev sequence's fit has a gap between pieces (a short piece left out)"
    for f in (0, 16, 70, 115, gaps[0], 199):
        hit = [i for i, p in enumerate(every) if p.first_frame <= f <= p.last_frame] or \
            [i for i, p in enumerate(every) if p.last_frame < f][-1:] + [i for i, p in enumerate(every)
                                                                         if p.first_frame > f][:1]
        lo, hi = max(min(hit) - REFIT_REACH, 0), min(max(hit) + REFIT_REACH, len(every) - 1)
        got = _pieces_around(db_session, game.id, f, f)
        spans = [(p.first_frame, p.last_frame) for p in got]
        assert all((p.first_frame, p.last_frame) in spans for p in every[lo:hi + 1]), f
        assert spans == sorted(spans) and set(spans) <= {(p.first_frame, p.last_frame) for p in every}


def test_the_cameras_an_edit_reads_are_those_of_the_whole_sequence(db_session, db_settings, stretch):
    """``sequence_columns`` reads the first system's views, and the later views of a camera only when its
    first view is not admitted: the same cameras (each camera's first admitted view in frame order) as the
    whole sequence gives (``sequence_arrays``), whether that view is the first, a later one, or none."""
    from app.services.issia.refit import sequence_columns
    from app.services.issia.trajectory import load_sequence, sequence_arrays

    import_issia(db_session, stretch, db_settings)
    game = db_session.scalars(sa.select(Game)).one()
    systems = _systems(db_session)
    for index in (0, 1, 2):  # cam3 admitted from frame 3 on (a different camera there), cam5 never
        _view(systems[index], "cam3").calibration.jac_0005 = 0.1
    later = _view(systems[3], "cam3").calibration
    later.camera = {**later.camera, "position_meters": [p + 0.5 for p in later.camera["position_meters"]]}
    for s in systems.values():
        cal = _view(s, "cam5").calibration
        cal.status, cal.camera = CalibrationStatus.REFUSED, None
    db_session.flush()
    columns = sequence_columns(db_session, game.id, db_settings)
    arrays = sequence_arrays(load_sequence(db_session, game.id), db_settings)
    assert columns.names == arrays.camera_names and columns.widths == arrays.widths
    for k, name in enumerate(columns.names):
        mine, whole = columns.cameras[k], arrays.cameras[k]
        assert (mine is None) == (whole is None), name
        if mine is not None:
            np.testing.assert_array_equal(mine.projection_matrix, whole.projection_matrix)
    by_name = dict(zip(columns.names, columns.first_admitted, strict=False))
    assert by_name["cam3"] == 3 and by_name["cam5"] is None and by_name["cam1"] == 0
    np.testing.assert_allclose(columns.cameras[columns.names.index("cam3")].C, later.camera["position_meters"])


def test_issia3d_export_writes_each_cameras_calibration(db_session, db_settings, stretch, tmp_path):
    """Issue 19: ``<sequence>/calibration/cam<k>.json`` beside ISSIA-3D.csv, the camera given at import (its
    projection), with which the CSV's ``ball_3D`` projects to within the CSV's own ``err_camK`` of the label."""
    import_issia(db_session, stretch, db_settings)
    report = export_issia3d(db_session, tmp_path / "out", include_all=True)
    folder = tmp_path / "out" / "issia-dev" / "calibration"
    assert report.calibrations == 6
    assert sorted(p.name for p in folder.iterdir()) == [f"cam{k}.json" for k in range(1, 7)]
    given = json.loads((stretch / "issia_calibration.json").read_text())
    cameras = {k: Camera.from_soccernet(json.loads((folder / f"cam{k}.json").read_text())) for k in range(1, 7)}
    for k, cam in cameras.items():
        np.testing.assert_allclose(cam.projection_matrix, Camera.from_soccernet(given[str(k)]).projection_matrix,
                                   rtol=1e-9, atol=1e-9)
    checked = 0
    for r in read_issia3d_csv(report.csv_paths[0]):
        if r.ball_3d is None:
            continue
        for k, (x, y, err, *_rest) in r.per_camera.items():
            if x is None or err is None:
                continue
            uv, _ = cameras[k].project(np.asarray([r.ball_3d], float))
            u, v = uv[0]
            assert np.hypot(u - x, v - y) == pytest.approx(err, abs=0.01)
            checked += 1
    assert checked >= 80  # 86 labelled views with a 3D ball in frames 0-39


def test_the_issia3d_export_imports_into_a_fresh_database_as_it_left(db_session, db_settings, stretch, tmp_path):
    """The export's sequence folder (ISSIA-3D.csv, issia_calibration.json) is an ISSIA folder: imported into an empty
    database it gives the same frames, point labels and cameras."""
    from app.db.session import make_engine

    import_issia(db_session, stretch, db_settings)
    export_issia3d(db_session, tmp_path / "out", include_all=True)
    folder = tmp_path / "out" / "issia-dev"
    assert sorted(json.loads((folder / "issia_calibration.json").read_text())) == [str(k) for k in range(1, 7)]
    url = f"sqlite:///{tmp_path / 'fresh.sqlite3'}"
    migrate_new_database(url)
    settings = db_settings.model_copy(update={"database_url": url})
    with Session(make_engine(url)) as fresh:
        import_issia(fresh, folder, settings)

        def state(session: Session) -> dict[tuple[int, str], tuple]:
            return {(s.frame_index, f.name): (f.ball_label.point if f.ball_label else None,
                                              np.round(Camera.from_soccernet(f.calibration.camera).projection_matrix,
                                                       6).tolist() if f.calibration and f.calibration.camera else None)
                    for s in _systems(session).values() for f in s.frames}

        assert state(fresh) == state(db_session) and len(state(fresh)) == 240


def test_the_issia3d_export_of_a_release_is_the_live_one_then_and_stays_the_same(db_session, db_settings, stretch,
                                                                                 tmp_path):
    import os
    import zipfile

    from app.services.exports.files import write_export_zip
    from app.services.releases.content import create_release

    def members(path: "os.PathLike[str]") -> dict[str, bytes]:
        with zipfile.ZipFile(os.fspath(path)) as zf:
            return {n: zf.read(n) for n in zf.namelist()}

    import_issia(db_session, stretch, db_settings)
    systems = _systems(db_session)
    for i in range(0, 12):
        decide_review(db_session, system_id=systems[i].id, status=ReviewStatus.ACCEPTED)
    db_session.commit()
    release = create_release(db_session, "issia-1")
    write_export_zip(db_session, "issia-3d", tmp_path / "live.zip", False, db_settings)
    made = write_export_zip(db_session, "issia-3d", tmp_path / "r1.zip", False, db_settings, release="issia-1")
    assert (made["sequences"], made["rows"], made["hash"]) == (1, 12, release.hash)
    ours, live = members(tmp_path / "r1.zip"), members(tmp_path / "live.zip")
    for name in ("v3d-release.json", "v3d-release/", "v3d-release/documents.jsonl.gz"):
        ours.pop(name)
    assert ours == live  # the same CSV, split and cameras as the database had then
    frame = _view(systems[5], "cam4")
    x, y = frame.ball_label.point
    update_ball_label(db_session, frame.id, point=[x + 6.0, y], settings=db_settings)
    write_export_zip(db_session, "issia-3d", tmp_path / "r2.zip", False, db_settings, release="issia-1")
    assert (tmp_path / "r2.zip").read_bytes() == (tmp_path / "r1.zip").read_bytes()
    write_export_zip(db_session, "issia-3d", tmp_path / "live2.zip", False, db_settings)
    assert members(tmp_path / "live2.zip") != live


def test_issia_stays_out_of_the_soccernet_v3d_export_and_its_views_are_named_and_split_per_camera(
        db_session, db_settings, shared_dir, tmp_path):
    """Issue 19: the SoccerNet-v3D export holds no ISSIA row; in the detector exports every ISSIA view has a
    file of its own, ``<sequence slug>-<hash>_cam<k>_<frame index, 6 digits>``, cameras 1-2 in test, 3-6 in
    train, and the files written are those reported (frames 10-17: each exported view decodes a video frame)."""
    from app.services.kinds import game_stem, kind_of
    from app.services.transfer.detector_export import export_coco, export_yolo
    from app.services.transfer.exporting import export_soccernet_v3d

    import_issia(db_session, write_issia_stretch(shared_dir, tmp_path / "issia-dev", 10, 17), db_settings)
    report = export_soccernet_v3d(db_session, tmp_path / "v3d", include_all=True)
    assert (report.games, report.systems, report.rows) == (0, 0, 0)
    with (tmp_path / "v3d" / "SNv3D.csv").open() as fh:
        assert len(list(csv.reader(fh))) == 1
    game = db_session.scalars(sa.select(Game)).one()
    s13 = _systems(db_session)[13]
    policy = kind_of(s13)
    assert policy.view_stem(game, _view(s13, "cam4")) == f"{game_stem(game)}_cam4_000013"
    assert game_stem(game).startswith("issia-dev-")
    assert [policy.split(s13, _view(s13, f"cam{k}")) for k in range(1, 7)] == ["test"] * 2 + ["train"] * 4

    yolo = export_yolo(db_session, tmp_path / "yolo", include_all=True)
    total = 0
    for split in ("train", "val", "test"):  # val: YOLO's validation systems, drawn from train
        images = sorted(p.stem for p in (tmp_path / "yolo" / "images" / split).iterdir())
        labels = sorted(p.stem for p in (tmp_path / "yolo" / "labels" / split).iterdir())
        assert images == labels and len(images) == yolo.images[split]
        cams = {s.split("_")[-2] for s in images}
        assert cams <= ({"cam1", "cam2"} if split == "test" else {"cam3", "cam4", "cam5", "cam6"})
        total += len(images)
    assert total > 30 and yolo.images["test"] > 0  # 8 frames of 6 cameras, views with an optimised box
    coco = export_coco(db_session, tmp_path / "coco", include_all=True)
    for split in ("train", "test"):
        doc = json.loads((tmp_path / "coco" / split / "instances.json").read_text())
        names = [im["file_name"] for im in doc["images"]]
        in_yolo = yolo.images[split] + (yolo.images["val"] if split == "train" else 0)
        assert len(names) == len(set(names)) == coco.images[split] == in_yolo
        assert sorted(p.name for p in (tmp_path / "coco" / split).iterdir()
                      if p.name != "instances.json") == sorted(names)


def test_an_edit_sets_back_to_pending_every_decided_system_whose_3d_ball_the_refit_moved(db_session, db_settings,
                                                                                        stretch):
    """Issue 28 item 3, the one rule for decisions after edits: an ISSIA edit re-fits its trajectory, which moves
    the 3D ball of neighbouring frames; each of those that was decided goes back to pending with the reason (and
    its own audit entry), the systems whose place on the trajectory did not change keep their decision."""
    import_issia(db_session, stretch, db_settings)
    systems = _systems(db_session)
    for s in systems.values():
        decide_review(db_session, system_id=s.id, status=ReviewStatus.ACCEPTED)
    db_session.expire_all()
    def point(s):  # the system's place on the trajectory, as stored
        tp = s.trajectory_point
        return json.dumps([tp.ball3d, tp.ball3d_smoothed, tp.source, tp.piece, tp.cam_list, tp.residuals_px,
                           tp.flagged], sort_keys=True, default=str)

    before = {i: point(s) for i, s in _systems(db_session).items()}
    cam3 = _view(_systems(db_session)[20], "cam3")
    x, y = cam3.ball_label.point
    update_ball_label(db_session, cam3.id, point=[x + 80.0, y], settings=db_settings, actor="ana")
    db_session.expire_all()
    moved, kept = [], []
    for i, s in _systems(db_session).items():
        (moved if point(s) != before[i] or i == 20 else kept).append(s)
    assert len(moved) > 1 and kept  # the re-fit reached neighbours, not the whole sequence
    for s in moved:
        assert s.review.status == ReviewStatus.PENDING, s.name
        if s.frame_index != 20:
            assert "re-fit after an edit of" in s.review.reset_reason and "by ana" in s.review.reset_reason
    assert all(s.review.status == ReviewStatus.ACCEPTED for s in kept)


def test_an_edit_bumps_the_version_of_every_undecided_system_whose_3d_ball_the_refit_moved(db_session, db_settings,
                                                                                          stretch):
    """The re-fit writes the moved neighbours' trajectory points and doubts with bulk statements; each of those
    systems' version (its ETag) moves with them, decided or not, so that a decision sent with the version its
    reviewer saw before the re-fit is refused (412) instead of landing on a 3D ball that has since moved."""
    import_issia(db_session, stretch, db_settings)
    db_session.expire_all()

    def point(s):
        tp = s.trajectory_point
        return json.dumps([tp.ball3d, tp.ball3d_smoothed, tp.source, tp.piece, tp.cam_list, tp.residuals_px,
                           tp.flagged], sort_keys=True, default=str)

    before = {i: (point(s), s.version) for i, s in _systems(db_session).items()}
    assert all(s.review is None or s.review.status == ReviewStatus.PENDING for s in _systems(db_session).values())
    cam3 = _view(_systems(db_session)[20], "cam3")
    x, y = cam3.ball_label.point
    update_ball_label(db_session, cam3.id, point=[x + 80.0, y], settings=db_settings, actor="ana")
    db_session.expire_all()
    after = _systems(db_session)
    moved = [i for i, s in after.items() if i != 20 and point(s) != before[i][0]]
    kept = [i for i, s in after.items() if point(s) == before[i][0]]
    assert moved and kept
    assert {i: after[i].version > before[i][1] for i in moved} == {i: True for i in moved}
    assert {i: after[i].version for i in kept if i != 20} == {i: before[i][1] for i in kept if i != 20}
    neighbour = after[moved[0]]
    with pytest.raises(StaleVersionError):
        decide_review(db_session, system_id=neighbour.id, status=ReviewStatus.ACCEPTED,
                      expected=[before[moved[0]][1]])
