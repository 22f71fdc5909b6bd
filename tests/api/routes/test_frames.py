"""``/api/frames``: the list, images (zip member, file, none), edits with their recomputation, bad
input that stores nothing, and an edit whose recomputation fails."""
from __future__ import annotations

import math

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.db.models import Frame
from app.services.curation import editing
from tests.accounts import Account, as_session

from ..factories import HEIGHT, WIDTH, Scene, png_bytes

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
# Served: the edits and their recomputation in one write unit, and the list's filters, are the engine's: those tests are
# marked ``engine``; images, refusals of bad input and compression answer the same on either engine.
pytestmark = pytest.mark.served


def _view(client: TestClient, scene: Scene) -> dict:
    answer = client.get(f"/api/systems/{scene.system_id}")
    assert answer.status_code == 200
    return answer.json()


# ----- images --------------------------------------------------------------------------------------
@pytest.mark.parametrize("view_index", [0, 1], ids=["zip-member", "file"])
def test_image_is_streamed_with_etag_and_304(client: TestClient, scene: Scene, view_index: int) -> None:
    url = _view(client, scene)["views"][view_index]["image_url"]
    assert url == f"/api/frames/{scene.frame_ids[view_index]}/image"
    answer = client.get(url)
    assert answer.status_code == 200
    assert answer.headers["content-type"] == "image/png"
    assert answer.content == png_bytes()
    etag = answer.headers["etag"]
    assert etag.startswith('"') and "max-age" in answer.headers["cache-control"]
    again = client.get(url, headers={"If-None-Match": etag})
    assert again.status_code == 304 and again.content == b"" and again.headers["etag"] == etag
    assert client.get(url, headers={"If-None-Match": '"something-else"'}).status_code == 200


def test_frame_without_image_is_404_with_a_clear_message(client: TestClient, scene: Scene) -> None:
    view = _view(client, scene)["views"][2]
    assert view["image_url"] is None
    answer = client.get(f"/api/frames/{scene.frame_ids[2]}/image")
    assert answer.status_code == 404
    assert "has no image" in answer.json()["detail"] and f"{WIDTH}x{HEIGHT}" in answer.json()["detail"]


@pytest.mark.parametrize("member", ["../1.png", "/etc/passwd", "a/../../1.png"])
def test_unsafe_member_names_are_refused(client: TestClient, scene: Scene, db_session: Session,
                                         member: str) -> None:
    frame = db_session.get(Frame, scene.frame_ids[0])
    frame.image_member = member
    db_session.commit()
    answer = client.get(f"/api/frames/{frame.id}/image")
    assert answer.status_code == 404 and "unsafe" in answer.json()["detail"]


def test_missing_member_and_unknown_frame_are_404(client: TestClient, scene: Scene, db_session: Session) -> None:
    frame = db_session.get(Frame, scene.frame_ids[0])
    frame.image_member = "999.png"
    db_session.commit()
    assert "999.png" in client.get(f"/api/frames/{frame.id}/image").json()["detail"]
    answer = client.get("/api/frames/777777/image")
    assert answer.status_code == 404 and "777777" in answer.json()["detail"]


# ----- ball edits ----------------------------------------------------------------------------------
@pytest.mark.engine
def test_patch_ball_recomputes_the_system(client: TestClient, scene: Scene) -> None:
    before = _view(client, scene)
    third = before["views"][2]
    box = third["ball"]["box"]
    moved = [box[0] + 8.0, box[1], box[2] + 8.0, box[3]]
    answer = client.patch(f"/api/frames/{scene.frame_ids[2]}/ball", json={"box": moved})
    assert answer.status_code == 200, answer.text
    after = answer.json()
    view = after["views"][2]
    assert view["ball"]["box"] == moved and view["ball"]["edited"] is True
    assert view["ball"]["original_box"] == box
    assert view["reprojection_error_px"] > 1.0 > third["reprojection_error_px"] + 0.5
    assert after["ball3d"] != before["ball3d"]
    assert after["views"][0]["optimised_box"] != before["views"][0]["optimised_box"]
    assert _view(client, scene) == after  # stored, not only answered


@pytest.mark.engine
def test_patch_point_and_removal(client: TestClient, scene: Scene) -> None:
    frame_id = scene.frame_ids[1]
    view = client.patch(f"/api/frames/{frame_id}/ball", json={"point": [400.0, 300.0]}).json()["views"][1]
    assert view["ball"]["kind"] == "point" and view["ball"]["point"] == [400.0, 300.0]
    view = client.patch(f"/api/frames/{frame_id}/ball", json={"box": None}).json()["views"][1]
    assert view["ball"]["kind"] is None and view["ball"]["box"] is None
    assert view["optimised_box"] is None


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ('{"box": [NaN, 10, 20, 30]}', "box"),
        ('{"box": [10, 10, Infinity, 30]}', "box"),
        ('{"box": [2000, 10, 2010, 30]}', "box"),  # entirely outside the 960x540 image
        ('{"box": [-30, 10, -10, 30]}', "box"),
        ('{"box": [30, 10, 20, 30]}', "box"),  # x2 < x1
        ('{"box": [10, 10, 20]}', "box"),
        ('{"box": [10, 10, 20, "a"]}', "box"),
        ('{"point": [480, 9999]}', "point"),
        ('{"box": [10, 10, 20, 30], "point": [1, 2]}', "box"),
        ('{"ball": [10, 10, 20, 30]}', "ball"),
        ("{}", "box"),
        ('{"box": [10, 10, 20, 3', "json"),  # truncated body
    ],
)
def test_bad_ball_edits_are_422_naming_the_field_and_store_nothing(
        client: TestClient, scene: Scene, body: str, field: str) -> None:
    before = _view(client, scene)
    answer = client.patch(f"/api/frames/{scene.frame_ids[0]}/ball", content=body,
                          headers={"Content-Type": "application/json"})
    assert answer.status_code == 422, answer.text
    assert field in answer.text
    assert _view(client, scene) == before


@pytest.mark.engine
def test_a_failing_recompute_leaves_stored_data_unchanged(app: FastAPI, scene: Scene, accounts: dict[str, Account],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args, **kwargs):
        raise RuntimeError("triangulation exploded")

    with as_session(TestClient(app, raise_server_exceptions=False), accounts["admin"]) as client:
        before = _view(client, scene)
        box = before["views"][0]["ball"]["box"]
        monkeypatch.setattr(editing, "recompute_system", broken)
        answer = client.patch(f"/api/frames/{scene.frame_ids[0]}/ball", json={"box": [b + 5 for b in box]})
        assert answer.status_code == 500
        monkeypatch.setattr(editing, "recompute_frame", broken)
        lines = {"Middle line": [[[480.0, 0.0], [480.0, 540.0]]]}
        answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json={"lines": lines})
        assert answer.status_code == 500
        assert _view(client, scene) == before


# ----- field lines ---------------------------------------------------------------------------------
@pytest.mark.engine
def test_put_field_lines_recalibrates_the_frame(client: TestClient, scene: Scene) -> None:
    before = _view(client, scene)["views"][0]
    lines = {cls: polys for cls, polys in before["field_lines"].items()}
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json={"lines": lines})
    assert answer.status_code == 200, answer.text
    after = answer.json()["views"][0]
    assert after["calibration"]["source"] == "computed"
    assert after["calibration"]["status"] in ("calibrated", "refused")
    assert set(after["field_lines"]) == set(lines)
    u = after["calibration"]["uncertainty"]  # issue 17: the camera's standard deviations from the fit
    if after["calibration"]["status"] == "calibrated":
        assert set(u) == {"position_m", "pan_deg", "tilt_deg", "roll_deg", "focal_px", "line_noise_px", "points"}
        assert set(u["position_m"]) == {"x", "y", "z"} and u["line_noise_px"] >= 1.0
        assert u["points"] == sum(len(p) for polys in lines.values() for p in polys)
    else:
        assert u is None


@pytest.mark.engine
def test_post_mirror_fixes_a_view_flagged_mirrored(client: TestClient, scene: Scene, db_session: Session,
                                                  db_settings) -> None:
    """A replay whose labels were mirrored after the import (with the camera they calibrate to) is
    flagged with its evidence; POST .../field-lines/mirror answers the recomputed system view, with
    the view calibrated where it stands, its error back to pixels and the flag gone."""
    from app.geometry.annotations import lines_from_json_lists, lines_to_json_lists, mirror_lines
    from app.geometry.camera import Camera
    from app.geometry.mirror import mirror_camera
    from app.services.derivation.recompute import recompute_system

    frame = db_session.get(Frame, scene.frame_ids[2])
    frame.field_lines.lines = lines_to_json_lists(mirror_lines(lines_from_json_lists(frame.field_lines.lines)))
    frame.calibration.camera = mirror_camera(Camera.from_soccernet(frame.calibration.camera)).to_soccernet()
    recompute_system(db_session, frame.system, db_settings)
    db_session.commit()
    before = _view(client, scene)["views"][2]
    assert "probably_mirrored" in before["calibration"]["flags"]
    evidence = before["calibration"]["mirror_evidence"]
    assert evidence["verdict"] == "probably_mirrored" and evidence["sentence"].startswith("Labels probably mirrored")
    assert [p["relation"] for p in evidence["pairs"]] == ["different", "different"]

    answer = client.post(f"/api/frames/{scene.frame_ids[2]}/field-lines/mirror")
    assert answer.status_code == 200, answer.text
    after = answer.json()["views"][2]
    assert "probably_mirrored" not in after["calibration"]["flags"]
    assert after["calibration"]["mirror_evidence"]["verdict"] == "as_labelled"
    assert after["calibration"]["source"] == "computed" and after["reprojection_error_px"] < 3.0
    assert after["field_lines"] == _view(client, scene)["views"][2]["field_lines"]  # stored
    assert math.dist(after["camera_position"][:2], scene.cameras[2].C[:2]) < 1.0


def test_post_mirror_is_404_for_an_unknown_frame_and_422_without_lines(client: TestClient, scene: Scene,
                                                                       db_session: Session) -> None:
    assert client.post("/api/frames/999999/field-lines/mirror").status_code == 404
    frame = db_session.get(Frame, scene.frame_ids[1])
    frame.field_lines.lines = {}
    db_session.commit()
    answer = client.post(f"/api/frames/{scene.frame_ids[1]}/field-lines/mirror")
    assert answer.status_code == 422 and answer.json()["field"] == "lines"


@pytest.mark.parametrize(
    ("lines", "expected"),
    [
        ({"Penalty spot": [[[1.0, 2.0], [3.0, 4.0]]]}, "Penalty spot"),
        ({"Middle line": [[[1.0, 2.0], [3.0, "x"]]]}, "lines"),
        ({"Middle line": [[]]}, "Middle line"),
        ({"Middle line": [[[1.0, 2.0, 3.0]]]}, "lines"),
    ],
)
def test_bad_field_lines_are_422_and_store_nothing(client: TestClient, scene: Scene, lines: dict,
                                                    expected: str) -> None:
    before = _view(client, scene)
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json={"lines": lines})
    assert answer.status_code == 422, answer.text
    assert expected in answer.text
    assert _view(client, scene) == before


def test_nan_in_field_lines_is_422_naming_the_class(client: TestClient, scene: Scene) -> None:
    body = '{"lines": {"Middle line": [[[480, 0], [NaN, 540]]]}}'
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", content=body,
                        headers={"Content-Type": "application/json"})
    assert answer.status_code == 422 and "Middle line" in answer.json()["detail"]
    assert answer.json()["field"] == "lines"


# ----- exclusion from the triangulation ------------------------------------------------------------
@pytest.mark.engine
def test_exclusion_leaves_the_view_out_of_every_pair_and_is_reversible(client: TestClient, scene: Scene) -> None:
    before = _view(client, scene)
    assert len([p for p in before["triangulation"]["pairs"] if p["kept"]]) == 3
    fid = scene.frame_ids[2]
    answer = client.post(f"/api/frames/{fid}/exclusion", json={"excluded": True})
    assert answer.status_code == 200
    view = answer.json()
    pairs = view["triangulation"]["pairs"]
    assert len(pairs) == 1 and fid not in (pairs[0]["view_a"], pairs[0]["view_b"])
    excluded = next(v for v in view["views"] if v["frame_id"] == fid)
    assert excluded["review"]["excluded"] is True and excluded["review"]["status"] == "pending"
    assert excluded["ball"]["box"] == next(v for v in before["views"] if v["frame_id"] == fid)["ball"]["box"]
    # the excluded view still gets the fused ball's reprojection (it is drawn), but no label doubt
    assert excluded["reprojection_error_px"] is not None
    assert not [d for d in view["doubts"] if d["frame_id"] == fid and d["accuses_label"]]
    restored = client.post(f"/api/frames/{fid}/exclusion", json={"excluded": False}).json()
    assert len(restored["triangulation"]["pairs"]) == 3
    assert next(v for v in restored["views"] if v["frame_id"] == fid)["review"]["excluded"] is False
    assert restored["ball3d"] == pytest.approx(before["ball3d"])


@pytest.mark.parametrize("body", [{}, {"excluded": "yes"}, {"excluded": True, "extra": 1}])
def test_bad_exclusion_is_422_and_changes_nothing(client: TestClient, scene: Scene, body: dict) -> None:
    answer = client.post(f"/api/frames/{scene.frame_ids[1]}/exclusion", json=body)
    assert answer.status_code == 422
    assert all(not v["review"]["excluded"] for v in _view(client, scene)["views"])
    assert client.post("/api/frames/999999/exclusion", json={"excluded": True}).status_code == 404


# ----- review and list -----------------------------------------------------------------------------
@pytest.mark.engine
def test_frame_review_shows_in_the_view(client: TestClient, scene: Scene) -> None:
    answer = client.post(f"/api/frames/{scene.frame_ids[1]}/review",
                         json={"status": "needs_fix", "comment": "mirrored lines"})
    assert answer.status_code == 200 and answer.json()["status"] == "needs_fix"
    view = _view(client, scene)["views"][1]
    assert view["review"]["status"] == "needs_fix" and view["review"]["comment"] == "mirrored lines"
    bad = client.post(f"/api/frames/{scene.frame_ids[1]}/review", json={"status": "maybe"})
    assert bad.status_code == 422 and "status" in bad.text


@pytest.mark.engine
def test_calibration_review_beside_the_ball_review(client: TestClient, scene: Scene) -> None:
    url = f"/api/frames/{scene.frame_ids[1]}"
    assert _view(client, scene)["views"][1]["review"]["calibration"] == {
        "status": "pending", "comment": "", "decided_at": None, "reset_reason": None}
    etag = client.get(url).headers["etag"]
    answer = client.post(f"{url}/calibration-review", json={"status": "rejected", "comment": "posts swapped"},
                         headers={"If-Match": etag})
    assert answer.status_code == 200 and answer.headers["etag"] != etag
    body = answer.json()
    assert body["status"] == "pending" and body["calibration"]["status"] == "rejected"
    assert body["calibration"]["comment"] == "posts swapped" and body["calibration"]["decided_at"]
    view = _view(client, scene)["views"][1]
    assert view["review"]["calibration"]["status"] == "rejected" and view["etag"] == answer.headers["etag"]
    stale = client.post(f"{url}/calibration-review", json={"status": "accepted"}, headers={"If-Match": etag})
    assert stale.status_code == 412
    bad = client.post(f"{url}/calibration-review", json={"status": "maybe"})
    assert bad.status_code == 422 and "status" in bad.text
    assert _view(client, scene)["views"][1]["review"]["calibration"]["status"] == "rejected"


@pytest.mark.engine
def test_frame_list_filters(client: TestClient, scene: Scene, db_session: Session) -> None:
    client.patch(f"/api/frames/{scene.frame_ids[2]}/ball", json={"box": [0.0, 0.0, 12.0, 12.0]})
    everything = client.get("/api/frames").json()
    assert everything["total"] == 3
    worst = client.get("/api/frames", params={"sort": "-error", "limit": 1}).json()["items"][0]
    assert worst["id"] == scene.frame_ids[2] and worst["reprojection_error_px"] > 100
    assert [f["id"] for f in client.get("/api/frames", params={"error_min": 100}).json()["items"]] == [
        scene.frame_ids[2]]
    assert client.get("/api/frames", params={"calibration": "none"}).json()["total"] == 0
    assert client.get("/api/frames", params={"calibration": "calibrated", "jac_min": 0.95}).json()["total"] == 0
    assert client.get("/api/frames", params={"jac_min": 0.85, "jac_max": 0.95}).json()["total"] == 3
    assert client.get("/api/frames", params={"calibration": "bogus"}).status_code == 422
    first = everything["items"][0]
    assert first["image_url"] and math.isclose(first["calibration"]["jac"]["0.005"], 0.9)


@pytest.mark.parametrize(("method", "path", "body"), [
    ("get", "image", None), ("patch", "ball", {"box": None}), ("put", "field-lines", {"lines": {}}),
    ("post", "field-lines/mirror", None), ("post", "exclusion", {"excluded": True}),
    ("post", "review", {"status": "accepted"}), ("post", "calibration-review", {"status": "accepted"}),
])
def test_frame_ids_beyond_the_id_column_are_422_naming_frame_id(client: TestClient, method: str, path: str,
                                                         body: dict | None) -> None:
    """Found by benchmarks/fuzz.py: such an id overflowed SQLite's driver (OverflowError, a 500)."""
    answer = client.request(method, f"/api/frames/972878476687272144215207837696/{path}", json=body)
    assert answer.status_code == 422, answer.text
    assert answer.json()["detail"][0]["loc"] == ["path", "frame_id"]


@pytest.mark.parametrize("path", ["ball", "field-lines", "exclusion", "review", "calibration-review"])
def test_a_body_that_is_not_utf8_json_is_422_naming_the_body(client: TestClient, scene: Scene, path: str) -> None:
    """Found by benchmarks/fuzz.py: FastAPI answered an undeclared 400 "There was an error parsing the body"."""
    method = {"ball": "PATCH", "field-lines": "PUT"}.get(path, "POST")
    before = client.get(f"/api/systems/{scene.system_id}").json()
    answer = client.request(method, f"/api/frames/{scene.frame_ids[0]}/{path}", content=b"\xc3\x28\xff{",
                            headers={"Content-Type": "application/json"})
    assert answer.status_code == 422, answer.text
    (error,) = answer.json()["detail"]
    assert error["loc"] == ["body"] and error["type"] == "body_unparsable" and "UnicodeDecodeError" in error["msg"]
    assert client.get(f"/api/systems/{scene.system_id}").json() == before


def test_nul_characters_in_a_body_are_422_naming_the_field(client: TestClient, scene: Scene) -> None:
    """Found by benchmarks/fuzz.py on PostgreSQL, whose text cannot hold NUL (a 500 there): refused on every
    database, nothing stored."""
    url = f"/api/frames/{scene.frame_ids[0]}/review"
    answer = client.post(url, json={"status": "accepted", "comment": "bad\x00comment"})
    assert answer.status_code == 422 and "comment: text must not contain NUL" in answer.json()["detail"][0]["msg"]
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json={"lines": {"Circle\x00": [[[1, 2]]]}})
    assert answer.status_code == 422 and "lines: text must not contain NUL" in answer.json()["detail"][0]["msg"]
    assert _view(client, scene)["views"][0]["review"]["status"] == "pending"


# ----- the projected pitch, at its own address ------------------------------------------------------
def test_pitch_lines_are_fetched_once_per_camera(client: TestClient, scene: Scene) -> None:
    """The system view names each view's projected pitch by its camera (issue 29: the lines were two thirds of every
    system answer); the address answers them with an ETag and, while it names the current camera, keeps for good."""
    view = _view(client, scene)["views"][0]
    assert "pitch_lines" not in view
    url = view["pitch_lines_url"]
    fid = scene.frame_ids[0]
    assert url.startswith(f"/api/frames/{fid}/pitch-lines?camera=")
    answer = client.get(url)
    assert answer.status_code == 200
    body = answer.json()
    assert body["frame_id"] == fid and url.endswith(body["camera"]) and body["lines"]
    assert "immutable" in answer.headers["cache-control"]
    assert body["lines"] == client.get(f"/api/frames/{fid}").json()["pitch_lines"]  # one frame's answer keeps them
    assert client.get(url, headers={"If-None-Match": answer.headers["etag"]}).status_code == 304
    # another camera (the lines moved by 40 px): another address; the old one is answered anew, not kept
    lines = {cls: [[[x + 40.0, y] for x, y in poly] for poly in polys] for cls, polys in view["field_lines"].items()}
    edited = client.put(f"/api/frames/{fid}/field-lines", json={"lines": lines}).json()["views"][0]
    if edited["pitch_lines_url"] is not None:
        assert edited["pitch_lines_url"] != url
        assert client.get(edited["pitch_lines_url"]).json()["lines"] != body["lines"]
    stale = client.get(url)
    assert stale.headers["cache-control"] == "private, no-cache" and stale.headers["etag"] != answer.headers["etag"]


def test_pitch_lines_of_an_unknown_frame_are_404(client: TestClient) -> None:
    assert client.get("/api/frames/2147483647/pitch-lines").status_code == 404


def test_large_answers_are_compressed_but_never_a_secret(client: TestClient, scene: Scene) -> None:
    """JSON answers above 1 KB go gzip-compressed to a client that accepts it; the answers carrying the CSRF token
    (or an API token) never do (BREACH: app.api.compression)."""
    answer = client.get(f"/api/systems/{scene.system_id}", headers={"Accept-Encoding": "gzip"})
    assert answer.headers.get("content-encoding") == "gzip" and answer.json()["id"] == scene.system_id
    me = client.get("/api/auth/me", headers={"Accept-Encoding": "gzip"})
    assert me.status_code == 200 and "content-encoding" not in me.headers
    plain = client.get(f"/api/systems/{scene.system_id}", headers={"Accept-Encoding": "identity"})
    assert "content-encoding" not in plain.headers


def _lines_of(client: TestClient, scene: Scene) -> dict:
    return {"lines": _view(client, scene)["views"][0]["field_lines"]}


@pytest.mark.parametrize(("method", "path", "body"), [
    ("patch", "/api/frames/{f2}/ball", lambda c, s: {"box": [10.0, 10.0, 22.0, 21.0]}),
    ("patch", "/api/frames/{f1}/ball", lambda c, s: {"box": None}),
    ("put", "/api/frames/{f0}/field-lines", _lines_of),
    ("post", "/api/frames/{f2}/exclusion", lambda c, s: {"excluded": True}),
], ids=["ball", "removal", "field-lines", "exclusion"])
@pytest.mark.engine
def test_an_edit_answers_the_system_as_stored(client: TestClient, scene: Scene, method: str, path: str, body) -> None:
    """Issue 29: an edit answers its system from the rows it has just written (no second round of queries); the
    answer is the page a later GET reads, pairs and doubts it dropped or added included."""
    ids = {f"f{i}": fid for i, fid in enumerate(scene.frame_ids)}
    answer = getattr(client, method)(path.format(**ids), json=body(client, scene))
    assert answer.status_code == 200, answer.text
    assert answer.json() == _view(client, scene)
