"""Every odd value is a 4xx naming its field, never a 500: lone surrogates in any text of a JSON body (they are no
Unicode text: neither the databases nor the answer's UTF-8 can hold one), ball boxes beyond the image's plausible
range (one check, ``app.datasets.labels.check_box``, shared by edits and imports), and ids beyond the database's
integer range (one id type, ``app.api.schemas.DbInt``, for every path parameter, and the system page's)."""
from __future__ import annotations

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.accounts import Account, as_session

from ..factories import Scene

#: ``"\\ud800"`` as JSON sends it: an escape the JSON parser turns into a lone surrogate.
SURROGATE = "\\ud800"


def _post_raw(client: TestClient, method: str, url: str, body: str) -> tuple[int, str]:
    answer = client.request(method, url, content=body.encode("ascii"), headers={"Content-Type": "application/json"})
    return answer.status_code, answer.text


@pytest.fixture
def lenient(app: FastAPI, accounts: dict[str, Account]):
    """The admin's browser session on a client that answers a server error as the 500 it is (no raise)."""
    with TestClient(app, raise_server_exceptions=False) as c:
        yield as_session(c, accounts["admin"])


def test_a_lone_surrogate_in_a_login_name_is_422_for_an_anonymous_client(app: FastAPI) -> None:
    """Was: 500 (the name could not be encoded to look the user up)."""
    with TestClient(app, raise_server_exceptions=False) as anonymous:
        status, text = _post_raw(anonymous, "POST", "/api/auth/login",
                                 f'{{"name": "ana{SURROGATE}", "password": "x"}}')
    assert status == 422, text
    assert "name: text must not contain a lone surrogate" in text


@pytest.mark.parametrize("case", ["comment", "provenance", "pass filter", "assignee", "filter key", "lines class"])
def test_a_lone_surrogate_in_any_text_of_a_body_is_422_naming_the_field(lenient: TestClient, scene: Scene,
                                                                         case: str) -> None:
    """Was: 500 for a comment, a provenance, a pass filter and an assignee (the text could not be stored or
    answered). Refused by the body's field types wherever it sits, keys included, naming where."""
    fid, sid = scene.frame_ids[0], scene.system_id
    method, url, body, field = {
        "comment": ("POST", f"/api/systems/{sid}/review", f'{{"status": "accepted", "comment": "{SURROGATE}"}}',
                    "comment"),
        "provenance": ("PATCH", f"/api/frames/{fid}/ball",
                       f'{{"box": [10, 10, 20, 20], "provenance": {{"doubt": "x{SURROGATE}"}}}}', "provenance.doubt"),
        "pass filter": ("POST", "/api/passes", f'{{"filter": {{"assignee": "{SURROGATE}"}}}}', "filter.assignee"),
        "assignee": ("POST", "/api/assignments", f'{{"assignee": "{SURROGATE}", "system_ids": [{sid}]}}',
                     "assignee"),
        "filter key": ("POST", "/api/assignments", f'{{"assignee": null, "filter": {{"{SURROGATE}": 1}}}}', "filter"),
        "lines class": ("PUT", f"/api/frames/{fid}/field-lines", f'{{"lines": {{"{SURROGATE}": []}}}}', "lines"),
    }[case]
    status, text = _post_raw(lenient, method, url, body)
    assert status == 422, text
    assert f"{field}: text must not contain a lone surrogate" in text, text
    assert lenient.get(f"/api/systems/{sid}").json()["review"]["status"] == "pending"  # nothing was stored


@pytest.mark.parametrize("box", [[0, 0, 1e308, 1e308], [-1e12, 10, 20, 20], [10, 10, 20, 5e9]])
def test_a_ball_box_beyond_the_images_plausible_range_is_422_naming_box(lenient: TestClient, scene: Scene,
                                                                        box: list[float]) -> None:
    """Was: ``[0, 0, 1e308, 1e308]`` passed the box check (finite, ordered, not entirely outside) and the 3D ball's
    computation failed: 500 "SVD did not converge". A box reaching farther than one image size beyond the image is
    no ball label."""
    fid = scene.frame_ids[0]
    before = lenient.get(f"/api/frames/{fid}").json()["ball"]
    answer = lenient.patch(f"/api/frames/{fid}/ball", json={"box": box})
    assert answer.status_code == 422, answer.text
    assert answer.json()["field"] == "box" and "plausible" in answer.json()["detail"]
    assert lenient.get(f"/api/frames/{fid}").json()["ball"] == before
    partly_outside = lenient.patch(f"/api/frames/{fid}/ball", json={"box": [-5.0, 10.0, 7.0, 22.0]})
    assert partly_outside.status_code == 200, partly_outside.text  # a ball at the border is still a label


@pytest.mark.parametrize("path", ["/systems/9000000000", "/systems/2147483648"])
def test_the_system_page_bounds_its_id_by_the_databases_integers(lenient: TestClient, path: str) -> None:
    """Was: the page checked its id against 2^63, not the column's range: on PostgreSQL (32-bit INTEGER ids) the
    look-up of ``/systems/9000000000`` failed, a 500. Now the same bound as every API path parameter: the page
    saying there is no such system (404)."""
    answer = lenient.get(path)
    assert answer.status_code == 404, answer.text[:300]
    assert "text/html" in answer.headers["content-type"]


def test_every_id_path_parameter_uses_the_one_id_type(app: FastAPI) -> None:
    """Every integer path parameter of the API is bounded by the database's integer range (``DbInt``): 422 for
    ``2**31``, however the route names it."""
    from app.db.types import DB_INT_MAX, DB_INT_MIN

    paths = app.openapi()["paths"]
    found = []
    for path, ops in paths.items():
        for method, op in ops.items():
            for p in op.get("parameters", []):
                if p["in"] == "path" and p["schema"].get("type") == "integer":
                    found.append((method, path, p["name"]))
                    assert (p["schema"].get("minimum"), p["schema"].get("maximum")) == (DB_INT_MIN, DB_INT_MAX), \
                        (method, path, p)
    assert len(found) >= 10
