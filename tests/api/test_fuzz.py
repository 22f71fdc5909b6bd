"""``benchmarks/fuzz.py`` in the suite: schemathesis against ``/openapi.json`` of the real app, every operation,
derandomised cases per operation and mode (the same cases every run: 3 in CI's suite, 25 in the slow tier; the
benchmark runs 50), as the admin's API token and as an anonymous client. Any 5xx, undeclared status, wrong content
type or answer off its schema
fails, with the curl line that reproduces it. The test's writes are rolled back with its transaction."""
from __future__ import annotations

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from app.services.accounts import users
from tests.accounts import Account
from tests.conftest import sizes

from .factories import Scene

pytest.importorskip("schemathesis", reason="schemathesis (the test extra) is needed by benchmarks/fuzz.py")


from benchmarks import fuzz  # after the skip: it needs schemathesis

pytestmark = pytest.mark.fuzz

#: Cases per operation and mode (positive, negative), CI's and the slow tier's: ~25 operations x 2 x that many.
EXAMPLES = sizes(3, 25)


def _failures(report) -> str:
    return "\n".join(f"{f.operation}: {f.check} (status {f.status}): {f.message}\n  {f.curl}" for f in report.failures)


@pytest.mark.parametrize("examples", EXAMPLES)
def test_fuzzing_as_admin_finds_no_server_error(app: FastAPI, scene: Scene, accounts: dict[str, Account],
                                                 examples: int) -> None:
    with TestClient(app):
        schema = fuzz.load_schema(app)
        # the user routes' name and token ids are the annotator's: the pass may disable it and revoke its tokens,
        # never its own principal (a 401 is a failure: tests/api/test_fuzz.py would otherwise fuzz the 401)
        target = accounts["annotator"].name
        with app.state.session_factory() as session:
            tokens = [users.issue_token(session, target, label=f"fuzz {i}").id for i in range(2)]
        path_ids = {"frame_id": list(scene.frame_ids), "system_id": [scene.system_id], "name": [target],
                    "token_id": tokens}
        headers = fuzz.admin_headers(accounts["admin"].token)
        report = fuzz.fuzz(schema, headers, examples=examples, path_ids=path_ids,
                           etag_of=fuzz.current_etags(app, headers))
    labels = {op.label for op in fuzz.operations(schema)}
    assert set(report.requests) == labels, "every operation of /openapi.json was sent"
    assert report.total >= 2 * len(labels)
    # the known ids, with their real ETags, reached the handlers behind the 404 and the 428 (a view and a
    # frame review answered 200)
    assert report.statuses["GET /api/systems/{system_id}"][200] >= 1
    assert report.statuses["POST /api/frames/{frame_id}/review"][200] >= 1
    assert report.server_errors == 0 and not report.failures, _failures(report)


@pytest.mark.parametrize("examples", sizes(2, 10))
def test_bodies_of_every_declared_and_one_undeclared_media_type_find_no_server_error(
        app: FastAPI, scene: Scene, accounts: dict[str, Account], examples: int) -> None:
    """Issue 27: each operation with a body gets bodies of each type it declares (the import route: JSON and
    multipart) and of one it does not (415 before it is read, never a 500)."""
    with TestClient(app):
        schema = fuzz.load_schema(app)
        headers = fuzz.admin_headers(accounts["admin"].token)
        path_ids = {"frame_id": list(scene.frame_ids), "system_id": [scene.system_id]}
        report = fuzz.fuzz_media_types(schema, headers, examples=examples, path_ids=path_ids,
                                       etag_of=fuzz.current_etags(app, headers))
    with_body = [op for op in fuzz.operations(schema) if op.get_request_payload_content_types()]
    assert len(with_body) >= 10
    assert "POST /api/imports [multipart/form-data]" in report.requests
    assert "POST /api/imports [application/json]" in report.requests
    for label, counts in report.statuses.items():  # every declared type reached its route (no 415)
        if fuzz.UNDECLARED_MEDIA_TYPE not in label:
            assert 415 not in counts, (label, counts)
    undeclared = {label: counts for label, counts in report.statuses.items() if fuzz.UNDECLARED_MEDIA_TYPE in label}
    assert len(undeclared) == len(with_body) and all(set(c) == {415} for c in undeclared.values()), undeclared
    assert report.server_errors == 0 and not report.failures, _failures(report)


@pytest.mark.parametrize("examples", sizes(3, 10))
def test_fuzzing_anonymously_answers_401_everywhere_but_the_public_routes(app: FastAPI, scene: Scene,
                                                                         examples: int) -> None:
    with TestClient(app):
        schema = fuzz.load_schema(app)
        report = fuzz.fuzz(schema, {}, examples=examples, anonymous=True)
    protected = {op.label for op in fuzz.operations(schema) if not fuzz.is_public(op)}
    assert set(report.requests) == protected and len(protected) >= 20
    assert all(set(counts) == {401} for counts in report.statuses.values()), report.statuses
    assert not report.failures, _failures(report)
