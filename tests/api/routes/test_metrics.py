"""``GET /metrics``: admins only (401 without a token, 403 with an annotator's, 200 with an admin's bearer token, as
Prometheus sends it), Prometheus' text format, and figures that follow what happened: requests by route template and
status, edits and recomputations, jobs by kind and state."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from app.core.metrics import UNMATCHED
from app.db.models import JobState
from app.services.jobs import runner as jobs
from tests.accounts import Account
from tests.conftest import sizes

from ..factories import Scene


def _samples(text: str) -> dict[tuple[str, frozenset], float]:
    """(sample name, its labels) -> value, from an exposition."""
    return {(s.name, frozenset(s.labels.items())): s.value
            for family in text_string_to_metric_families(text) for s in family.samples}


def _scrape(client: TestClient, admin: Account) -> dict[tuple[str, frozenset], float]:
    answer = client.get("/metrics", headers=admin.bearer)
    assert answer.status_code == 200, answer.text
    assert answer.headers["content-type"] == "text/plain; version=0.0.4; charset=utf-8"
    return _samples(answer.text)


def _requests(samples: dict, route: str, method: str, status: int) -> float:
    return samples.get(("v3d_http_request_duration_seconds_count",
                        frozenset({"route": route, "method": method, "status": str(status)}.items())), 0.0)


def test_metrics_need_an_admins_token(anonymous: TestClient, accounts: dict[str, Account]) -> None:
    assert anonymous.get("/metrics").status_code == 401
    assert anonymous.get("/metrics", headers=accounts["annotator"].bearer).status_code == 403
    assert anonymous.get("/metrics", headers=accounts["reviewer"].bearer).status_code == 403
    assert anonymous.get("/metrics", headers={"Authorization": "Bearer v3d_not-a-token"}).status_code == 401
    assert anonymous.get("/metrics", headers=accounts["admin"].bearer).status_code == 200


def test_requests_are_counted_by_route_template_method_and_status(anonymous: TestClient,
                                                                    accounts: dict[str, Account]) -> None:
    admin = accounts["admin"]
    before = _scrape(anonymous, admin)
    for system_id in (1, 2, 3):  # three ids, one series; refused before routing, yet named by the route they asked
        assert anonymous.get(f"/api/systems/{system_id}").status_code == 401
    assert anonymous.get("/no/such/page-7").status_code == 404
    assert anonymous.get("/api/health").status_code == 200
    after = _scrape(anonymous, admin)
    assert _requests(after, "/api/systems/{system_id}", "GET", 401) - _requests(
        before, "/api/systems/{system_id}", "GET", 401) == 3
    assert _requests(after, UNMATCHED, "GET", 404) - _requests(before, UNMATCHED, "GET", 404) == 1
    assert _requests(after, "/api/health", "GET", 200) - _requests(before, "/api/health", "GET", 200) == 1
    assert not any("/api/systems/1" in str(labels) or "page-7" in str(labels) for _, labels in after)
    # the scrape before this one is counted too: a histogram whose buckets hold every request
    labels = frozenset({"route": "/metrics", "method": "GET", "status": "200"}.items())
    assert after[("v3d_http_request_duration_seconds_bucket", labels | {("le", "+Inf")})] == after[
        ("v3d_http_request_duration_seconds_count", labels)] >= 1


@pytest.mark.parametrize("methods", sizes(40, 408))
def test_what_a_client_makes_up_adds_no_series(anonymous: TestClient, accounts: dict[str, Account],
                                               methods: int) -> None:
    """Methods, paths and route parameters a client makes up are counted in series from a closed set: every made-up
    method as ``other``, every unknown path as one route; the exposition does not grow with them."""
    admin = accounts["admin"]
    anonymous.get("/metrics", headers=admin.bearer)  # the scrape's own series, before the size is taken
    for method in ("BREW", "GET"):  # every series these requests can reach, made once
        anonymous.request(method, "/no/such/page-0")
        anonymous.request(method, "/api/systems/0")
    before = anonymous.get("/metrics", headers=admin.bearer)
    for n in range(methods):
        made_up = f"X{n}-PROBE"
        assert anonymous.request(made_up, f"/no/such/page-{n}").status_code in (404, 405)
        assert anonymous.request(made_up, f"/api/systems/{n}").status_code in (401, 405)
        assert anonymous.get(f"/no/such/{n}/page").status_code == 404
    after = anonymous.get("/metrics", headers=admin.bearer)
    series = {labels for (name, labels) in _samples(after.text) if name == "v3d_http_request_duration_seconds_count"}
    assert series == {labels for (name, labels) in _samples(before.text)
                      if name == "v3d_http_request_duration_seconds_count"}
    assert {dict(labels)["method"] for labels in series} <= {"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS",
                                                                 "CONNECT", "TRACE", "other"}
    assert not any("PROBE" in text or "page-" in text for text in (after.text, after.text.lower()))
    assert len(after.content) < len(before.content) + 1024  # the same series: only their counts and sums grew
    counted = _samples(after.text)
    other = sum(v for (name, labels), v in counted.items()
                if name == "v3d_http_request_duration_seconds_count" and dict(labels)["method"] == "other")
    assert other >= 2 * methods


def test_an_edit_counts_one_edit_and_its_recomputation(client: TestClient, scene: Scene,
                                                       accounts: dict[str, Account]) -> None:
    admin = accounts["admin"]
    before = _scrape(client, admin)
    box = client.get(f"/api/systems/{scene.system_id}").json()["views"][2]["ball"]["box"]
    moved = [box[0] + 8.0, box[1], box[2] + 8.0, box[3]]
    assert client.patch(f"/api/frames/{scene.frame_ids[2]}/ball", json={"box": moved}).status_code == 200
    assert client.patch(f"/api/frames/{scene.frame_ids[2]}/ball", json={"box": "wrong"}).status_code == 422
    after = _scrape(client, admin)

    def edits(samples: dict) -> float:
        return sum(v for (name, _), v in samples.items() if name == "v3d_edits_total")

    assert edits(after) - edits(before) == 1  # the refused edit stored nothing and counts nothing
    assert [dict(labels)["action"] for (name, labels), v in after.items()
            if name == "v3d_edits_total" and v > before.get((name, labels), 0.0)] == ["ball.edit"]
    recomputed = ("v3d_system_recomputations_total", frozenset())
    assert after[recomputed] - before.get(recomputed, 0.0) >= 1
    assert _requests(after, "/api/frames/{frame_id}/ball", "PATCH", 200) - _requests(
        before, "/api/frames/{frame_id}/ball", "PATCH", 200) == 1
    assert _requests(after, "/api/frames/{frame_id}/ball", "PATCH", 422) - _requests(
        before, "/api/frames/{frame_id}/ball", "PATCH", 422) == 1


def test_jobs_are_shown_by_kind_and_state_from_the_database(client: TestClient, db_session,
                                                            accounts: dict[str, Account]) -> None:
    jobs.submit(db_session, "recompute", {})
    jobs.submit(db_session, "recompute", {})
    counts = jobs.count_jobs(db_session)
    samples = _scrape(client, accounts["admin"])
    for kind in jobs.JOB_KINDS:
        for state in JobState:
            assert samples[("v3d_jobs", frozenset({"kind": kind, "state": state.value}.items()))] == counts.get(
                (kind, state.value), 0)
    assert counts[("recompute", "queued")] >= 2
    assert samples[("v3d_jobs_queued", frozenset())] == sum(n for (_, s), n in counts.items() if s == "queued")
