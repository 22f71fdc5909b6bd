"""``/api/games`` and ``/api/systems``: the queue (filters, sort, pages, progress) and the system view."""
from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Calibration
from app.geometry.doubts import LABEL_KINDS

from ..factories import BALL, HEIGHT, WIDTH, Scene, make_game, make_system

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
# Served: the queue's orders, filters, counts and pages are SQL the two engines write differently: those tests are
# marked ``engine``; refusals of bad parameters and the page of a stale link answer the same on either engine.
pytestmark = pytest.mark.served


@pytest.fixture
def queue(db_session: Session, db_settings: Settings) -> dict[str, Scene]:
    """Four systems in two games:

    * ``exact``   (game 1, "2.png"):  exact labels, JaC 0.90 -> error ~0;
    * ``shifted`` (game 1, "10.png"): one box 6 px off, JaC 0.80 -> the largest error;
    * ``lonely``  (game 1, "1.png"):  one labelled view -> no 3D ball, JaC 0.95;
    * ``other``   (game 2, "3.png"):  exact, JaC 0.85.
    """
    g1 = make_game(db_session)
    g2 = make_game(db_session, match="2016-01-01 - 15-00 Arsenal 2 - 0 Everton")
    return {
        "exact": make_system(db_session, db_settings, g1, "2.png", jac=0.90),
        "shifted": make_system(db_session, db_settings, g1, "10.png", jac=0.80, shift_px=(0.0, 0.0, 6.0)),
        "lonely": make_system(db_session, db_settings, g1, "1.png", jac=0.95, labelled=(True, False, False)),
        "other": make_system(db_session, db_settings, g2, "3.png", jac=0.85),
    }


def _ids(answer: dict) -> list[int]:
    return [item["id"] for item in answer["items"]]


@pytest.mark.engine
def test_games_list_their_systems(client: TestClient, queue: dict[str, Scene]) -> None:
    games = client.get("/api/games").json()
    assert [(g["match"], g["systems"]) for g in games] == [
        ("2015-02-21 - 18-00 Chelsea 1 - 1 Burnley", 3), ("2016-01-01 - 15-00 Arsenal 2 - 0 Everton", 1)]


@pytest.mark.engine
def test_worst_error_order_puts_the_largest_error_first_and_systems_without_ball_last(
        client: TestClient, queue: dict[str, Scene]) -> None:
    answer = client.get("/api/systems", params={"sort": "-worst_error"}).json()
    ids = _ids(answer)
    assert ids[0] == queue["shifted"].system_id
    assert ids[-1] == queue["lonely"].system_id
    assert answer["total"] == 4
    rows = {r["id"]: r for r in answer["items"]}
    lonely = rows[queue["lonely"].system_id]
    assert lonely["ball3d"] is None and lonely["worst_error_px"] is None
    assert (lonely["views_total"], lonely["views_admitted"], lonely["views_labelled"]) == (3, 3, 1)
    shifted = rows[queue["shifted"].system_id]
    assert shifted["worst_error_px"] > 1.0 > rows[queue["exact"].system_id]["worst_error_px"]
    assert shifted["lowest_jac"] == pytest.approx(0.80)


@pytest.mark.engine
def test_default_order_puts_the_most_label_doubts_first(client: TestClient, queue: dict[str, Scene]) -> None:
    items = client.get("/api/systems?sort=-doubts").json()["items"]
    doubts = [r["label_doubts"] for r in items]
    assert doubts == sorted(doubts, reverse=True)
    for r in items:
        assert r["label_doubts"] == sum(n for k, n in r["doubt_counts"].items() if k in LABEL_KINDS)


@pytest.mark.engine
def test_default_order_puts_the_work_to_do_first_and_a_decided_system_after(
        client: TestClient, queue: dict[str, Scene]) -> None:
    """A rejected system leaves the top of the default queue: the pending ones come first (the worst error first, none
    has a label doubt), decided systems after them, and a fixed one (back to re-review) is work to do again."""
    first = _ids(client.get("/api/systems").json())
    assert first[0] == queue["shifted"].system_id and first[-1] == queue["lonely"].system_id  # no 3D ball last
    etag = client.get(f"/api/systems/{first[0]}").headers["etag"]
    assert client.post(f"/api/systems/{first[0]}/review", json={"status": "rejected"},
                       headers={"If-Match": etag}).status_code == 200
    after = client.get("/api/systems").json()["items"]
    assert [r["id"] for r in after] == first[1:] + first[:1]
    assert [r["review"]["status"] if r["review"] else "pending" for r in after][:3] == ["pending"] * 3
    assert _ids(client.get("/api/systems?sort=severity").json())[-1] == first[0]  # both directions: work first


@pytest.mark.parametrize(
    ("sort", "expected"),
    [
        ("lowest_jac", ["shifted", "other", "exact", "lonely"]),
        ("-lowest_jac", ["lonely", "exact", "other", "shifted"]),
        ("name", ["lonely", "exact", "shifted", "other"]),  # game first, then 1 < 2 < 10 (numeric)
        ("worst_error", None),  # smallest first, still without-ball last
    ],
)
@pytest.mark.engine
def test_sorts(client: TestClient, queue: dict[str, Scene], sort: str, expected: list[str] | None) -> None:
    ids = _ids(client.get("/api/systems", params={"sort": sort}).json())
    if expected is None:
        assert ids[0] != queue["shifted"].system_id and ids[-1] == queue["lonely"].system_id
    else:
        assert ids == [queue[k].system_id for k in expected]


@pytest.mark.engine
def test_filters_by_game_jac_and_error(client: TestClient, queue: dict[str, Scene]) -> None:
    def get(**p):
        return set(_ids(client.get("/api/systems", params=p).json()))
    assert get(game_id=queue["other"].game_id) == {queue["other"].system_id}
    assert get(jac_min=0.85, jac_max=0.9) == {queue["exact"].system_id, queue["other"].system_id}
    assert get(error_min=1.0) == {queue["shifted"].system_id}
    assert get(error_max=1.0) == {queue["exact"].system_id, queue["other"].system_id}


@pytest.mark.engine
def test_review_status_filter_and_progress_counts(client: TestClient, queue: dict[str, Scene]) -> None:
    sid = queue["exact"].system_id
    answer = client.post(f"/api/systems/{sid}/review", json={"status": "accepted", "comment": "fine"})
    assert answer.status_code == 200
    assert answer.json()["status"] == "accepted" and answer.json()["decided_at"]
    pending = client.get("/api/systems", params={"status": "pending"}).json()
    assert sid not in _ids(pending) and pending["total"] == 3
    # progress is over the queue's other filters, not the status one
    assert pending["counts"] == {"pending": 3, "accepted": 1, "rejected": 0, "needs_fix": 0, "fixed": 0}
    accepted = client.get("/api/systems", params={"status": "accepted"}).json()
    assert _ids(accepted) == [sid] and accepted["items"][0]["review"]["comment"] == "fine"
    # without filters the pending count is the table's rest (queue._status_counts); with one, a GROUP BY: they agree
    rejected = queue["other"].system_id
    assert client.post(f"/api/systems/{rejected}/review", json={"status": "rejected"}).status_code == 200
    every = client.get("/api/systems").json()
    assert every["counts"] == {"pending": 2, "accepted": 1, "rejected": 1, "needs_fix": 0, "fixed": 0}
    assert every["total"] == 4
    by_game = {}
    for game in {scene.game_id for scene in queue.values()}:
        for status, n in client.get("/api/systems", params={"game_id": game}).json()["counts"].items():
            by_game[status] = by_game.get(status, 0) + n
    assert by_game == every["counts"]


@pytest.mark.engine
def test_pagination(client: TestClient, queue: dict[str, Scene]) -> None:
    full = _ids(client.get("/api/systems").json())
    pages = [_ids(client.get("/api/systems", params={"limit": 3, "offset": o}).json()) for o in (0, 3)]
    assert pages[0] + pages[1] == full and len(pages[1]) == 1


@pytest.mark.parametrize(
    ("params", "field"),
    [({"sort": "worst"}, "sort"), ({"jac_min": 1.5}, "jac_min"), ({"limit": 0}, "limit"),
     ({"status": "done"}, "status"), ({"error_min": 5, "error_max": 1}, "error_min")],
)
def test_bad_queue_parameters_are_422_naming_the_field(client: TestClient, params: dict, field: str) -> None:
    answer = client.get("/api/systems", params=params)
    assert answer.status_code == 422
    assert field in str(answer.json()["detail"])


@pytest.mark.parametrize(
    ("url", "field"),
    [("/api/systems/5608156813967030754306491984216326144", "system_id"),
     ("/api/systems/-2147483649", "system_id"),
     ("/api/systems?offset=9223372036854775808", "offset"),
     ("/api/systems?game_id=99999999999999999999", "game_id"),
     ("/api/frames?system_id=-99999999999999999999", "system_id"),
     ("/api/frames?offset=99999999999999999999", "offset")],
)
def test_ids_beyond_the_id_columns_are_422_naming_the_parameter(client: TestClient, url: str, field: str) -> None:
    """Found by benchmarks/fuzz.py: such an id overflowed SQLite's driver (OverflowError, a 500); ids are
    bounded by PostgreSQL's 32-bit INTEGER (tests/api/test_postgres.py)."""
    answer = client.get(url)
    assert answer.status_code == 422, answer.text
    assert answer.json()["detail"][0]["loc"][-1] == field
    assert client.get("/api/systems/2147483647").status_code == 404  # the largest id is looked up


def test_system_view_carries_the_ui_contract(client: TestClient, queue: dict[str, Scene]) -> None:
    scene = queue["exact"]
    view = client.get(f"/api/systems/{scene.system_id}").json()
    assert view["name"] == "2.png" and view["game"]["id"] == scene.game_id
    assert view["review"] == {"status": "pending", "comment": "", "decided_at": None, "excluded": False,
                              "batch_id": None, "reset_reason": None,
                              "calibration": None}  # a system has no calibration decision
    assert view["views"][0]["review"]["calibration"] == {"status": "pending", "comment": "", "decided_at": None,
                                                         "reset_reason": None}
    np.testing.assert_allclose(view["ball3d"], BALL, atol=1e-6)
    tri = view["triangulation"]
    assert tri["status"] == "triangulated" and tri["tau_px"] == 20.0 and len(tri["pairs"]) == 3
    assert {p["view_a"] for p in tri["pairs"]} <= set(scene.frame_ids)
    assert [v["frame_id"] for v in view["views"]] == scene.frame_ids
    first = view["views"][0]
    assert (first["role"], first["width"], first["height"]) == ("action", WIDTH, HEIGHT)
    assert first["image_url"] is None  # this scene stores no image
    assert first["calibration"]["admitted"] is True
    assert first["calibration"]["jac"]["0.005"] == pytest.approx(0.90)
    np.testing.assert_allclose(first["camera_position"], scene.cameras[0].C)
    # pitch lines at the image's resolution, clipped to it, at their own address; the centre circle is in view
    pitch = client.get(first["pitch_lines_url"]).json()["lines"]
    classes = {line["class"] for line in pitch}
    assert "Circle central" in classes or "Middle line" in classes
    pts = np.concatenate([np.array(line["points"]) for line in pitch])
    assert pts.min() >= -0.01 and pts[:, 0].max() <= WIDTH + 0.01 and pts[:, 1].max() <= HEIGHT + 0.01
    assert first["field_lines"] and all(len(pt) == 2 for polys in first["field_lines"].values()
                                        for poly in polys for pt in poly)
    ball = first["ball"]
    assert ball["kind"] == "box" and ball["edited"] is False and ball["box"] == ball["original_box"]
    centre = [(ball["box"][0] + ball["box"][2]) / 2, (ball["box"][1] + ball["box"][3]) / 2]
    np.testing.assert_allclose(first["reprojected_ball"], centre, atol=0.01)
    assert first["reprojection_error_px"] == pytest.approx(0.0, abs=1e-6)
    assert first["optimised_box"]["d_px"] > 0 and len(first["optimised_box"]["box"]) == 4


@pytest.mark.engine
def test_prev_and_next_follow_the_queue_given(client: TestClient, queue: dict[str, Scene]) -> None:
    order = _ids(client.get("/api/systems").json())
    middle = client.get(f"/api/systems/{order[1]}").json()
    assert (middle["prev_id"], middle["next_id"]) == (order[0], order[2])
    first = client.get(f"/api/systems/{order[0]}").json()
    assert first["prev_id"] is None
    # within one game sorted by name; a system outside the filter still gets its would-be neighbours
    game = {"game_id": queue["exact"].game_id, "sort": "name"}
    exact = client.get(f"/api/systems/{queue['exact'].system_id}", params=game).json()
    assert (exact["prev_id"], exact["next_id"]) == (queue["lonely"].system_id, queue["shifted"].system_id)
    other = client.get(f"/api/systems/{queue['other'].system_id}", params=game).json()
    assert other["prev_id"] == queue["shifted"].system_id and other["next_id"] is None
    # by error, "other" (error ~0, another game) keeps its own error as its key: it sorts before
    # the ball-less "lonely", not last as a system without aggregates would
    by_error = {"game_id": queue["exact"].game_id, "sort": "-worst_error"}
    other = client.get(f"/api/systems/{queue['other'].system_id}", params=by_error).json()
    assert other["prev_id"] in (queue["shifted"].system_id, queue["exact"].system_id)
    assert other["next_id"] in (queue["exact"].system_id, queue["lonely"].system_id)


def test_unknown_system_is_404_naming_the_id(client: TestClient) -> None:
    answer = client.get("/api/systems/424242")
    assert answer.status_code == 404 and "424242" in answer.json()["detail"]
    answer = client.post("/api/systems/424242/review", json={"status": "accepted"})
    assert answer.status_code == 404 and "424242" in answer.json()["detail"]


@pytest.mark.parametrize("path", ["/systems/424242", "/systems/not-an-id", "/systems/99999999999999999999999"])
def test_stale_system_link_is_a_404_page_back_to_the_queue(client: TestClient, path: str) -> None:
    """A person following a stale link to a system page got raw JSON (``{"detail": ...}``): now a small
    HTML page says the system does not exist and links back to the queue, with the link's filters."""
    answer = client.get(path, params={"sort": "name", "status": "pending"})
    assert answer.status_code == 404
    assert answer.headers["content-type"].startswith("text/html")
    page = answer.text
    assert "<title>System not found" in page and "does not exist" in page
    assert path.rsplit("/", 1)[1] in page
    assert 'href="/?sort=name&amp;status=pending" data-testid="queue-link"' in page
    assert client.head(path).status_code == 404
    bare = client.get(path).text
    assert 'href="/" data-testid="queue-link"' in bare


def test_stale_system_link_escapes_the_id(client: TestClient) -> None:
    answer = client.get("/systems/%3Cscript%3Ealert(1)%3Cb%3E")
    assert answer.status_code == 404
    assert "<script>" not in answer.text and "&lt;script&gt;alert(1)&lt;b&gt;" in answer.text


def test_unknown_query_parameters_are_ignored(client: TestClient, queue: dict[str, Scene]) -> None:
    sid = queue["exact"].system_id
    assert client.get(f"/api/systems/{sid}", params={"page": 3, "game": 1}).status_code == 200
    assert client.get("/api/systems", params={"page": 3}).json()["total"] == 4


@pytest.mark.engine
def test_queue_rows_count_views_flagged_mirrored(client: TestClient, db_session: Session,
                                                 queue: dict[str, Scene]) -> None:
    """The queue said nothing of mirrored labels: a system whose replay was flagged
    ``probably_mirrored`` looked clean in the queue (empty doubts) until it was opened. The count is
    stored with the flag by the recomputation (``update_summary``), never aggregated per request."""
    from app.db.models import Frame
    from app.geometry.calibration.result import MIRROR_FLAG
    from app.services.derivation.recompute import update_summary

    frame = db_session.get(Frame, queue["other"].frame_ids[1])
    frame.calibration.flags = ["rig_assisted", MIRROR_FLAG]
    update_summary(frame.system, frame.system.triangulation)
    db_session.commit()
    rows = {r["id"]: r for r in client.get("/api/systems").json()["items"]}
    assert rows[queue["other"].system_id]["views_flagged"] == 1
    assert rows[queue["exact"].system_id]["views_flagged"] == 0
    views = client.get(f"/api/systems/{queue['other'].system_id}").json()["views"]
    assert [v["calibration"]["probably_mirrored"] for v in views] == [False, True, False]


@pytest.mark.engine
def test_queue_rows_carry_the_review_time(client: TestClient, queue: dict[str, Scene]) -> None:
    """The queue's rows answered ``review.decided_at: null`` for every system, decided or not: the
    queue query never read the decision's time (the schema filled in its default)."""
    sid = queue["exact"].system_id
    decided = client.post(f"/api/systems/{sid}/review", json={"status": "accepted"}).json()["decided_at"]
    rows = {r["id"]: r for r in client.get("/api/systems").json()["items"]}
    assert decided is not None
    assert rows[sid]["review"]["decided_at"] == decided
    assert rows[queue["other"].system_id]["review"]["decided_at"] is None


@pytest.mark.engine
def test_queue_rows_count_views_above_tau_by_the_system_pages_rule(
        client: TestClient, db_session: Session, db_settings: Settings, queue: dict[str, Scene]) -> None:
    """The queue said nothing of a view whose reprojection error is above tau (the system page's
    "error > tau" doubt): it showed only once the system was opened. ``views_above_tau`` counts the
    admitted labelled views above tau by the rule the system view's ``error_above_tau`` uses: the
    error scaled to the rule's reference width (960-px views: x 2), against the stored tau."""
    from app.db.models import Frame, Triangulation
    from app.services.derivation.recompute import update_summary

    g = make_game(db_session, match="2017-03-04 - 12-30 Liverpool 3 - 1 Arsenal")
    # the replay's box 40 px off: by class (ball_rule "weights") its pair with the action meets under the grass
    # (outside the play volume) and is dropped; the ball of the two others leaves errors 11.7, 1.3 and 20.1 px, one
    # above tau = 20 raw, 23.4, 2.5 and 40.2 px scaled to 1920: two views above tau
    by_class = db_settings.model_copy(update={"ball_rule": "weights"})
    wrong = make_system(db_session, by_class, g, "4.png", shift_px=(0.0, 0.0, 40.0))

    def rows() -> dict[int, dict]:
        return {r["id"]: r for r in client.get("/api/systems").json()["items"]}

    def page_verdicts() -> list[bool]:
        return [v["error_above_tau"] for v in client.get(f"/api/systems/{wrong.system_id}").json()["views"]]

    view = client.get(f"/api/systems/{wrong.system_id}").json()
    tri = view["triangulation"]
    assert (tri["tau_px"], tri["rule"], tri["reference_width_px"]) == (20.0, "max_scaled_1920", 1920.0)
    errors = [v["reprojection_error_px"] for v in view["views"]]
    assert sum(e > tri["tau_px"] for e in errors) == 1  # raw pixels would count one
    expected = [e * 1920.0 / WIDTH > tri["tau_px"] for e in errors]
    assert expected == [True, False, True]
    # the page shows the error in the rule's scale, as the server computed it (the UI never rescales)
    scaled = [e * 1920.0 / WIDTH for e in errors]
    assert [v["reprojection_error_scaled_px"] for v in view["views"]] == pytest.approx(scaled)
    assert page_verdicts() == expected
    assert rows()[wrong.system_id]["views_above_tau"] == 2
    assert {r["views_above_tau"] for sid, r in rows().items() if sid != wrong.system_id} == {0}

    # a view that is not admitted is not counted (its stored error stays; the page still flags it)
    frame = db_session.get(Frame, wrong.frame_ids[0])
    frame.calibration.admitted = False
    update_summary(frame.system, frame.system.triangulation)  # what the recomputation stores with it
    db_session.commit()
    assert rows()[wrong.system_id]["views_above_tau"] == 1
    assert page_verdicts() == expected

    # the stored rule decides the scaling: max_px compares raw pixels, and only the replay is above tau
    tri = db_session.get(Triangulation, wrong.system_id)
    tri.rule = "max_px"
    update_summary(tri.system, tri)
    db_session.commit()
    assert client.get(f"/api/systems/{wrong.system_id}").json()["triangulation"]["reference_width_px"] is None
    assert page_verdicts() == [False, False, True]
    assert rows()[wrong.system_id]["views_above_tau"] == 1


def test_error_reference_widths_follow_the_pair_error_rules() -> None:
    """The reference width of each rule is the one ``app.geometry.pair_error.pair_error`` scales by."""
    from app.geometry.pair_error import PAIR_ERROR_RULES, RULE_REFERENCE_WIDTH_PX, pair_error, rule_reference_width_px

    assert set(RULE_REFERENCE_WIDTH_PX) <= set(PAIR_ERROR_RULES)
    for rule in PAIR_ERROR_RULES:
        reference = rule_reference_width_px(rule)
        scaled = 3.0 * reference / 960.0 if reference is not None else 3.0
        assert pair_error((3.0, 3.0), (960.0, 960.0), rule) == pytest.approx(scaled), rule


@pytest.mark.parametrize("sort", ["-doubts", "doubts", "-worst_error", "worst_error", "lowest_jac", "-lowest_jac",
                                  "name", "-name"])
@pytest.mark.engine
def test_prev_and_next_follow_the_listed_order_for_every_sort(client: TestClient, queue: dict[str, Scene],
                                                               sort: str) -> None:
    """prev_id / next_id come from two keyset queries on the stored sort keys (NULLs last, ties by id);
    they must name exactly the rows the queue lists before and after, also for a system outside the
    filtered queue (it is placed where it would be)."""
    client.post(f"/api/systems/{queue['exact'].system_id}/review", json={"status": "accepted"})
    for params in ({}, {"status": "pending"}):
        ids = _ids(client.get("/api/systems", params={**params, "sort": sort, "limit": 500}).json())
        for i, sid in enumerate(ids):
            view = client.get(f"/api/systems/{sid}", params={**params, "sort": sort}).json()
            assert view["prev_id"] == (ids[i - 1] if i > 0 else None), (params, sid)
            assert view["next_id"] == (ids[i + 1] if i + 1 < len(ids) else None), (params, sid)
    # the accepted system, outside the pending queue, sits between the rows it sorts between
    full = _ids(client.get("/api/systems", params={"sort": sort, "limit": 500}).json())
    pending = _ids(client.get("/api/systems", params={"status": "pending", "sort": sort, "limit": 500}).json())
    sid = queue["exact"].system_id
    view = client.get(f"/api/systems/{sid}", params={"status": "pending", "sort": sort}).json()
    before = [i for i in full[:full.index(sid)] if i in pending]
    after = [i for i in full[full.index(sid) + 1:] if i in pending]
    assert view["prev_id"] == (before[-1] if before else None)
    assert view["next_id"] == (after[0] if after else None)


@pytest.mark.engine
def test_cursor_pages_follow_the_offset_pages(client: TestClient, queue: dict[str, Scene]) -> None:
    """``after=next_cursor`` / ``before=prev_cursor`` walk the same pages as ``offset`` (every sort is
    checked against the order in tests/services/curation/test_queue_paging.py)."""
    full = _ids(client.get("/api/systems", params={"sort": "name"}).json())
    first = client.get("/api/systems", params={"sort": "name", "limit": 3}).json()
    assert _ids(first) == full[:3] and first["prev_cursor"] is None and first["offset"] == 0
    second = client.get("/api/systems", params={"sort": "name", "limit": 3, "after": first["next_cursor"]}).json()
    assert _ids(second) == full[3:] and second["next_cursor"] is None and second["offset"] is None
    back = client.get("/api/systems", params={"sort": "name", "limit": 3, "before": second["prev_cursor"]}).json()
    assert _ids(back) == full[:3] and back["prev_cursor"] is None and back["next_cursor"] == first["next_cursor"]


@pytest.mark.parametrize("field", ["after", "before"])
def test_bad_cursors_are_422_naming_the_field(client: TestClient, queue: dict[str, Scene], field: str) -> None:
    made = client.get("/api/systems", params={"sort": "name", "limit": 1}).json()["next_cursor"]
    for cursor, says in ((made, "sort='name'"), ("garbage!", "not a queue cursor")):
        answer = client.get("/api/systems", params={"sort": "-worst_error", field: cursor})
        assert answer.status_code == 422
        assert answer.json()["field"] == field and says in answer.json()["detail"]


def _tampered(cursor: str, index: int, value) -> str:
    import base64
    import json

    sort, values = json.loads(base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4)))
    values[index] = value
    raw = json.dumps([sort, values]).replace('"INF"', "1e400")  # JSON for a number beyond any float
    return base64.urlsafe_b64encode(raw.encode()).decode().rstrip("=")


@pytest.mark.parametrize("sort", ["-worst_error", "name", "doubts", "lowest_jac"])
def test_forged_cursors_are_422_naming_the_field(client: TestClient, queue: dict[str, Scene], sort: str) -> None:
    """Issue 27, item 6. Was: a cursor whose system id exceeds any integer answered 500 (the database or its driver
    refused the comparison); so did other values a column cannot hold. Every forged value is now a 422 naming the
    cursor's field, on SQLite and PostgreSQL."""
    made = client.get("/api/systems", params={"sort": sort, "limit": 1}).json()["next_cursor"]
    assert made is not None
    forged = [_tampered(made, -1, v) for v in (10**20, 2**63, 2**31, -1, 0, "7", 1.5, None, True)]
    forged += [made[:-3], "A" + made, "x" * 5000, "WzFd", "W10"]  # damaged, too long, not a pair, empty
    if sort == "name":
        forged += [_tampered(made, 0, "a\x00b"), _tampered(made, 3, 10**20), _tampered(made, 0, 7)]
    else:
        forged += [_tampered(made, 0, "INF"), _tampered(made, 0, "text")]
    for field in ("after", "before"):
        for cursor in forged:
            answer = client.get("/api/systems", params={"sort": sort, field: cursor})
            assert answer.status_code == 422, (cursor, answer.text)
            said = answer.json()
            if isinstance(said["detail"], list):  # FastAPI's form, for a cursor longer than any made
                assert said["detail"][0]["loc"] == ["query", field], said
            else:
                assert said["field"] == field and "cursor" in said["detail"], said
            assert len(answer.text) < 600
    assert client.get("/api/systems", params={"sort": sort, "after": made}).status_code == 200


def test_ids_beyond_any_integer_are_422_naming_the_parameter(client: TestClient, queue: dict[str, Scene]) -> None:
    """Every path and query id of every GET route, beyond the databases' integers or negative beyond them: a 422
    naming the parameter, never a 500 (PostgreSQL's INTEGER is 32-bit; SQLite's driver overflows past 64 bits)."""
    import re

    paths = client.app.openapi()["paths"]
    checked = 0
    for path, ops in paths.items():
        if "get" not in ops:
            continue
        params = [p for p in ops["get"].get("parameters", []) if p["schema"].get("type") == "integer"
                  or any(s.get("type") == "integer" for s in p["schema"].get("anyOf", []))]
        for param in params:
            for huge in ("99999999999999999999", str(2**63), str(-(2**63) - 1), str(2**31)):
                url = path
                query = {}
                if param["in"] == "path":
                    url = path.replace("{" + param["name"] + "}", huge)
                else:
                    query = {param["name"]: huge}
                url = re.sub(r"\{[a-z_]+\}", str(queue["exact"].system_id), url)
                answer = client.get(url, params=query)
                assert answer.status_code == 422, (url, query, answer.status_code, answer.text[:200])
                assert any(e["loc"][-1] == param["name"] for e in answer.json()["detail"]), answer.text
                checked += 1
    assert checked >= 20
    page = client.get("/systems/99999999999999999999")  # the UI page of a system
    assert page.status_code == 404 and "System not found" in page.text


@pytest.mark.engine
def test_the_queue_filters_by_the_camera_source_and_refuses_an_unknown_one(client: TestClient, db_session: Session,
                                                                           queue: dict[str, Scene]) -> None:
    cal = db_session.get(Calibration, queue["shifted"].frame_ids[1])
    cal.flags = [*cal.flags, "few_lines", "player_assisted", "rig_assisted"]  # as the players place a camera
    db_session.commit()
    assert _ids(client.get("/api/systems", params={"camera": "player_assisted"}).json()) == [queue["shifted"].system_id]
    assert _ids(client.get("/api/systems", params={"camera": "rig_assisted"}).json()) == [queue["shifted"].system_id]
    assert len(_ids(client.get("/api/systems").json())) == 4
    r = client.get("/api/systems", params={"camera": "lines"})
    assert r.status_code == 422 and "camera" in r.text


def test_every_3d_ball_carries_its_sigma_and_the_queue_filters_by_it(client: TestClient,
                                                                     queue: dict[str, Scene]) -> None:
    """The system view and the queue rows give each stored 3D ball's sigma (metres, its least certain direction);
    ``sigma_min`` / ``sigma_max`` keep the systems whose ball's sigma lies in the range (none without a ball); a
    range upside down is a 422 naming it."""
    view = client.get(f"/api/systems/{queue['exact'].system_id}").json()
    sigma = view["ball_sigma_m"]
    assert isinstance(sigma, float) and 0.0 < sigma < 1.0 and view["triangulation"]["sigma_m"] == sigma
    lonely = client.get(f"/api/systems/{queue['lonely'].system_id}").json()
    assert lonely["ball3d"] is None and lonely["ball_sigma_m"] is None
    rows = {r["id"]: r for r in client.get("/api/systems").json()["items"]}
    assert rows[queue["exact"].system_id]["ball_sigma_m"] == sigma
    with_ball = {s.system_id for name, s in queue.items() if name != "lonely"}
    assert set(_ids(client.get("/api/systems?sigma_max=1").json())) == with_ball
    assert _ids(client.get("/api/systems?sigma_min=1").json()) == []
    assert set(_ids(client.get(f"/api/systems?sigma_min={sigma}&sigma_max={sigma}").json())) >= {
        queue["exact"].system_id}
    bad = client.get("/api/systems?sigma_min=2&sigma_max=1")
    assert bad.status_code == 422 and "sigma_min" in bad.text


@pytest.mark.engine
def test_each_3d_ball_says_what_backs_it_and_the_queue_filters_and_sorts_by_it(
        client: TestClient, db_session: Session, db_settings: Settings, queue: dict[str, Scene]) -> None:
    """The system view and each queue row carry the stored tier of the 3D ball and its reasons: three views that agree
    vouch for it, two views only leave it unconfirmed, a system without a ball is ``none``. ``ball_evidence=`` lists
    exactly the systems of that tier, ``sort=ball_evidence`` puts the vouched first and the systems without a ball
    last (reversed by ``-ball_evidence``), and an unknown tier is a 422 naming the parameter."""
    from app.db.models import Game

    game = db_session.get(Game, queue["exact"].game_id)
    two = make_system(db_session, db_settings, game, "4.png", labelled=(True, True, False))
    exact = client.get(f"/api/systems/{queue['exact'].system_id}").json()
    assert exact["ball_evidence"] == "vouched", exact["ball_evidence_reasons"]
    assert "three views agree" in exact["ball_evidence_reasons"]
    lonely = client.get(f"/api/systems/{queue['lonely'].system_id}").json()
    assert lonely["ball_evidence"] == "none" and lonely["ball_evidence_reasons"] == []
    pair = client.get(f"/api/systems/{two.system_id}").json()
    assert pair["ball_evidence"] == "unconfirmed"
    assert pair["ball_evidence_reasons"][0] == "only two views: nothing else checks it"
    rows = {r["id"]: r for r in client.get("/api/systems").json()["items"]}
    assert rows[two.system_id]["ball_evidence"] == "unconfirmed"
    assert rows[queue["exact"].system_id]["ball_evidence_reasons"] == exact["ball_evidence_reasons"]
    for tier in ("vouched", "unconfirmed", "doubted", "none"):
        listed = _ids(client.get("/api/systems", params={"ball_evidence": tier}).json())
        assert sorted(listed) == sorted(i for i, r in rows.items() if r["ball_evidence"] == tier), tier
    order = [rows[i]["ball_evidence"] for i in _ids(client.get("/api/systems?sort=ball_evidence").json())]
    rank = ["vouched", "unconfirmed", "doubted", "none"]
    assert order == sorted(order, key=rank.index) and order[0] == "vouched" and order[-1] == "none"
    backwards = [rows[i]["ball_evidence"] for i in _ids(client.get("/api/systems?sort=-ball_evidence").json())]
    assert backwards == order[::-1]
    bad = client.get("/api/systems?ball_evidence=sure")
    assert bad.status_code == 422 and "ball_evidence" in bad.text
