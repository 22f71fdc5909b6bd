"""The demo through the whole service chain: imported, calibrated, triangulated, and its planted
problems at the head of the review queue where a newcomer sees them first, each named by its doubt."""
from __future__ import annotations

import numpy as np
from sqlalchemy.orm import Session

from app.api.view_schemas import SystemView
from app.core.config import Settings
from app.services.curation import queue
from app.services.curation.system_page import system_page
from app.services.transfer import importing
from tests.demo.support import Demo


def test_demo_imports_into_the_review_queue(demo: Demo, db_session: Session, db_settings: Settings) -> None:
    report = importing.import_soccernet_v3(db_session, demo.root, db_settings)
    n_views = len(demo.views())
    assert (report.games, report.systems, report.frames) == (1, len(demo.truth["systems"]), n_views)
    assert report.calibrated == n_views and report.refused == 0

    page = queue.list_systems(db_session, limit=100)
    assert page.total == len(demo.truth["systems"]) and page.counts["pending"] == page.total

    by_action = {}
    for item in page.items:
        view = SystemView.of(system_page(db_session, item.id)).model_dump(mode="json", by_alias=True)
        action = next(v["name"] for v in view["views"] if v["role"] == "action")
        by_action[action] = (item, view)
    truth = {s["action"]: s for s in demo.truth["systems"]}
    assert set(by_action) == set(truth)

    # Clean systems: every view is admitted and the fused ball lands near the truth.
    for action, (item, view) in by_action.items():
        if truth[action]["problems"]:
            continue
        assert item.views_admitted == item.views_total, action
        assert view["ball3d"] is not None, action
        err = np.linalg.norm(np.array(view["ball3d"]) - truth[action]["ball_3d"])
        assert err < 1.0, (action, err)

    # The queue's default order (most label doubts first) opens on the planted problems, each named at
    # its view by a doubt of its kind: the misplaced ball box, the mirrored labels, the missing ball
    # label (with a box suggested where the other views put the ball) and the near-duplicate viewpoint.
    by_kind = {p["kind"]: (a, p["image"]) for a, s in truth.items() for p in s["problems"]}
    planted = {by_kind[k][0] for k in by_kind}
    head = []
    for item in page.items[: len(planted)]:
        head.append(next(a for a, (it, _) in by_action.items() if it.id == item.id))
    assert set(head) == planted, head
    expected = {"wrong_ball_box": "ball_off_consensus", "mirrored_lines": "mirrored_labels",
                "missing_ball": "ball_missing", "near_duplicate_viewpoint": "near_duplicate_view"}
    for problem, kind in expected.items():
        action, image = by_kind[problem]
        doubts = by_action[action][1]["doubts"]
        if problem == "near_duplicate_viewpoint":  # either of the two views may be named
            assert any(d["kind"] == kind and d["frame"] in (action, image) for d in doubts), doubts
        else:
            assert any(d["kind"] == kind and d["frame"] == image for d in doubts), (problem, doubts)
    clean = [a for a in truth if not truth[a]["problems"]]
    assert not [d for a in clean for d in by_action[a][1]["doubts"] if d["accuses_label"]]
    action, image = by_kind["missing_ball"]
    view = next(v for v in by_action[action][1]["views"] if v["name"] == image)
    doubt = next(d for d in by_action[action][1]["doubts"] if d["kind"] == "ball_missing")
    x1, y1, x2, y2 = doubt["suggestion"]["box"]
    tx1, ty1, tx2, ty2 = demo.views()[image]["precise_box"]
    assert np.hypot((x1 + x2 - tx1 - tx2) / 2, (y1 + y2 - ty1 - ty2) / 2) < 0.01 * view["width"]

    action, image = by_kind["near_duplicate_viewpoint"]
    view = by_action[action][1]
    ids = {v["name"]: v["frame_id"] for v in view["views"]}
    pair = next(p for p in view["triangulation"]["pairs"] if {p["view_a"], p["view_b"]} == {ids[action], ids[image]})
    assert not pair["kept"] and pair["reason"] in ("parallax_below_min", "baseline_below_min"), pair
