"""Issue 29, item 1: one recomputation computes each pair of ball rays once (``PairGeometryMemo``) and the mirror
evidence, the triangulation and the doubts' consensus judge that one answer by their own rules. On the synthetic
SoccerNet-v3 dev set (40 systems, mirrored views, wrong labels, near-duplicate replays), every derived row of every
system is the same as when each judge computes its own pairs."""
from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa

from app.core.config import Settings
from app.db.models import System
from app.geometry import triangulation
from app.services.derivation import cameras
from app.services.derivation.recompute import load_for_recompute, recompute_system
from app.services.transfer.importing import import_soccernet_v3


class _Unshared(triangulation.PairGeometryMemo):
    """Each ask computed anew: what the judges did before they shared the memo."""

    def __call__(self, a, b):
        self.asked += 1
        self.computed += 1
        return triangulation.pair_geometry(a, b)


def _values(row) -> dict | None:
    """A derived row's column values, without its ids and the time stamps a recomputation writes."""
    if row is None:
        return None
    skip = {"id", "system_id", "frame_id", "computed_at", "updated_at"}
    return {a.key: getattr(row, a.key) for a in sa.inspect(type(row)).column_attrs if a.key not in skip}


def _derived(system: System) -> tuple:
    """What a recomputation of ``system`` wrote, as plain values: per view its calibration, reprojection and
    optimised box, the triangulation, pairs and doubts, and the system's queue figures."""
    frames = {f.id: [_values(f.calibration), _values(f.reprojection), _values(f.optimised_box)] for f in system.frames}
    tri = system.triangulation
    summary = {k: getattr(system, k) for k in ("doubt_counts", "label_doubts", "review_status", "views_total",
                                               "views_calibrated", "views_admitted", "views_labelled", "lowest_jac",
                                               "worst_error_px", "views_flagged", "views_above_tau")}
    return (frames, _values(tri), [_values(p) for p in tri.pairs] if tri is not None else [],
            [_values(d) for d in system.doubts], summary)


def _recomputed_with(session, ids: list[int], settings: Settings, monkeypatch: pytest.MonkeyPatch, memo_name: str,
                     memo) -> dict[int, tuple]:
    """Every system of ``ids`` loaded and recomputed with the process memo ``cameras.<memo_name>`` set to ``memo``:
    what each wrote (:func:`_derived`), by id; rolled back after."""
    monkeypatch.setattr(cameras, memo_name, memo)
    out = {}
    with session.no_autoflush:
        systems = load_for_recompute(session, ids, predictions=settings.max_predictions_per_frame)
        for sid in ids:
            recompute_system(session, systems[sid], settings)
            out[sid] = _derived(systems[sid])
    session.rollback()
    return out


def test_shared_pair_geometry_changes_no_derived_row_of_the_dev_set(shared_dir: Path, fresh_session_factory,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The memo shared by every recomputation of the process (``cameras.PAIR_GEOMETRY``) gives the rows of judges that
    each compute their own pairs; recomputing the same systems again computes no pair anew."""
    session = fresh_session_factory("dev")
    settings = Settings(_env_file=None, database_url=str(session.get_bind().url), calibration_workers=1)
    import_soccernet_v3(session, shared_dir / "data/synthetic/soccernet-v3-dev", settings)
    ids = session.scalars(sa.select(System.id).order_by(System.id)).all()
    assert len(ids) == 40

    def run(memo) -> dict[int, tuple]:
        return _recomputed_with(session, ids, settings, monkeypatch, "PAIR_GEOMETRY", memo)

    unshared_memo = _Unshared()
    unshared = run(unshared_memo)
    memo = triangulation.PairGeometryMemo(max_entries=cameras.PAIRS)
    shared = run(memo)
    for sid in ids:
        assert shared[sid] == unshared[sid], f"system {sid}"
    assert memo.asked == unshared_memo.asked  # the same questions
    print(f"pair geometry: {memo.asked} asks, {memo.computed} computed")
    assert memo.computed < 0.7 * memo.asked  # most from the memo: the triangulation's and the consensus's pairs
    computed = memo.computed
    again = run(memo)  # the same labels and cameras, loaded anew: every pair known (cameras.stored_camera)
    assert again == shared and memo.computed == computed


def test_an_edit_computes_only_the_pairs_of_the_view_it_changed(shared_dir: Path, fresh_session_factory,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A moved ball label of one view of a four-view system: its pairs (as calibrated and mirrored) are computed again,
    the three pairs of the other views (and their mirrored pairs) come from the last recomputation; the rows are those
    of a recomputation that computes every pair."""
    session = fresh_session_factory("dev")
    settings = Settings(_env_file=None, database_url=str(session.get_bind().url), calibration_workers=1)
    import_soccernet_v3(session, shared_dir / "data/synthetic/soccernet-v3-dev", settings)
    systems = load_for_recompute(session, session.scalars(sa.select(System.id).order_by(System.id)).all(),
                                 predictions=settings.max_predictions_per_frame)
    system = next(s for s in systems.values() if len(s.frames) == 4 and all(
        f.ball_label is not None and f.ball_label.box is not None and f.calibration is not None
        and f.calibration.admitted for f in s.frames))
    memo = triangulation.PairGeometryMemo(max_entries=cameras.PAIRS)
    monkeypatch.setattr(cameras, "PAIR_GEOMETRY", memo)
    with session.no_autoflush:
        recompute_system(session, system, settings)
        before = memo.computed
        label = system.frames[0].ball_label
        label.box = [label.box[0] + 3.0, label.box[1], label.box[2] + 3.0, label.box[3]]
        recompute_system(session, system, settings)
        new = memo.computed - before
        shared = _derived(system)
        monkeypatch.setattr(cameras, "PAIR_GEOMETRY", _Unshared())
        recompute_system(session, system, settings)
        assert _derived(system) == shared
    # the first recomputation computed every pair; after the edit the 3 pairs of the untouched views and their 3
    # mirrored pairs come from the memo: only the moved view's pairs (as calibrated, mirrored, the consensus's)
    print("pairs computed: first", before, "after the edit", new)
    assert 0 < new <= before - 6, (before, new)
    session.rollback()


def test_a_memo_answers_a_pair_once_and_never_another_camera() -> None:
    """The memo's key is the cameras' identity and the pixels: the same pair is computed once; an equal but distinct
    camera object, or another pixel, is computed anew (a camera is never trusted by its id alone)."""
    import numpy as np

    from app.geometry.camera import Camera
    from app.geometry.triangulation import BallObservation, PairGeometryMemo, pair_geometry

    def cam(pan: float, pos: list[float]) -> Camera:
        return Camera.from_parameters(focal_px=1500.0, principal_point=(960.0, 540.0), pan_deg=pan, tilt_deg=80.0,
                                      roll_deg=0.0, position_m=pos)

    a_cam, b_cam = cam(0.0, [0, 60, -15]), cam(90.0, [-70, 0, -15])
    ball = np.array([1.0, 2.0, -0.11])
    a = BallObservation(1, a_cam, a_cam.project(ball.reshape(1, 3))[0][0], 1920)
    b = BallObservation(2, b_cam, b_cam.project(ball.reshape(1, 3))[0][0], 1920)
    memo = PairGeometryMemo()
    g = memo(a, b)
    assert memo(BallObservation(7, a_cam, a.point_px.copy(), 960), b) is g  # ids and widths do not enter the geometry
    assert (memo.asked, memo.computed) == (2, 1)
    np.testing.assert_allclose(g.point, ball, atol=1e-6)
    fresh = pair_geometry(a, b)
    assert (g.baseline_m, g.parallax_deg, g.errors_px) == (fresh.baseline_m, fresh.parallax_deg, fresh.errors_px)
    twin = cam(0.0, [0, 60, -15])  # equal, another object
    assert memo(BallObservation(1, twin, a.point_px, 1920), b) is not g
    assert memo(BallObservation(1, a_cam, a.point_px + [5.0, 0.0], 1920), b) is not g
    assert memo.computed == 3


class _UnsharedPlayers(cameras.PairPlayersMemo):
    """Each ask computed anew."""

    def __call__(self, camera_a, feet_a, size_a, camera_b, feet_b, size_b):
        self.asked += 1
        self.computed += 1
        from app.geometry.calibration.players import pair_players_disagreement
        return pair_players_disagreement(camera_a, feet_a, size_a, camera_b, feet_b, size_b)


def test_the_players_memo_changes_no_derived_row_and_a_ball_edit_asks_it_nothing_new(
        shared_dir: Path, fresh_session_factory, monkeypatch: pytest.MonkeyPatch) -> None:
    """Judged by evidence, each kept pair's cameras are compared on their players (``players_disagree``). The memo
    shared by every recomputation (``cameras.PAIR_PLAYERS``) gives every derived row of the dev set that a comparison
    made anew on every ask gives (72 comparisons); the same systems loaded and recomputed again, or a ball label moved
    (cameras and players as they were), compute none."""
    session = fresh_session_factory("dev")
    settings = Settings(_env_file=None, database_url=str(session.get_bind().url), calibration_workers=1,
                        ball_rule="evidence")
    import_soccernet_v3(session, shared_dir / "data/synthetic/soccernet-v3-dev", settings)
    ids = session.scalars(sa.select(System.id).order_by(System.id)).all()

    def run(memo) -> dict[int, tuple]:
        return _recomputed_with(session, ids, settings, monkeypatch, "PAIR_PLAYERS", memo)

    unshared_memo = _UnsharedPlayers(max_entries=cameras.PAIRS)
    unshared = run(unshared_memo)
    memo = cameras.PairPlayersMemo(max_entries=cameras.PAIRS)
    shared = run(memo)
    assert shared == unshared and memo.asked == unshared_memo.asked > 0
    computed = memo.computed
    assert run(memo) == shared and memo.computed == computed  # loaded anew: every pair known (stored_camera)

    with session.no_autoflush:
        systems = load_for_recompute(session, ids, predictions=settings.max_predictions_per_frame)
        system = max(systems.values(), key=lambda s: len(s.frames))
        recompute_system(session, system, settings)
        computed = memo.computed
        label = next(f.ball_label for f in system.frames if f.ball_label is not None and f.ball_label.box is not None)
        label.box = [label.box[0] + 3.0, label.box[1], label.box[2] + 3.0, label.box[3]]
        recompute_system(session, system, settings)
    assert memo.computed == computed
    session.rollback()


def test_the_players_memo_answers_a_pair_once_and_never_other_cameras_or_players() -> None:
    """Keyed by the cameras' identity, the foot points and the sizes: the same pair computed once and equal to the
    comparison made anew; an equal but distinct camera object, or a foot point moved, computed anew."""
    import numpy as np

    from app.geometry.calibration.grass import foot_world
    from app.geometry.calibration.players import pair_players_disagreement
    from app.geometry.camera import Camera

    def cam(pan: float, pos: list[float]) -> Camera:
        return Camera.from_parameters(focal_px=1500.0, principal_point=(960.0, 540.0), pan_deg=pan, tilt_deg=80.0,
                                      roll_deg=0.0, position_m=pos)

    a_cam, b_cam = cam(0.0, [0, 60, -15]), cam(90.0, [-70, 0, -15])
    grass = np.array([[-3.0, 2.0], [1.0, -4.0], [5.0, 3.0], [2.0, 8.0]])

    def feet(c: Camera) -> dict:
        uv = c.project(foot_world(grass, c.C))[0]
        return {("Player team left", str(i)): uv[i] for i in range(len(grass))}

    fa, fb, size = feet(a_cam), feet(b_cam), (1920, 1080)
    memo = cameras.PairPlayersMemo(max_entries=8)
    got = memo(a_cam, fa, size, b_cam, fb, size)
    assert got == pair_players_disagreement(a_cam, fa, size, b_cam, fb, size) and got is not None and got < 1.0
    assert memo(a_cam, {k: v.copy() for k, v in fa.items()}, size, b_cam, fb, size) == got
    assert (memo.asked, memo.computed) == (2, 1)
    memo(cam(0.0, [0, 60, -15]), fa, size, b_cam, fb, size)  # equal, another object
    moved = dict(fa)
    moved[("Player team left", "0")] = fa[("Player team left", "0")] + [30.0, 0.0]
    memo(a_cam, moved, size, b_cam, fb, size)
    assert memo.computed == 3
    with pytest.raises(ValueError, match="at least 2"):
        cameras.PairPlayersMemo(max_entries=1)
