"""Every query parameter of every route, sent odd values (dates out of range once converted to UTC, integers beyond
any database's, NaN and infinities, NUL, a lone surrogate's bytes, empty text, a parameter repeated, very long
text): a 4xx (a GET's 422 naming the field), never a 500. The operations and their parameters are read from the
app's own OpenAPI document, so a route added later is walked too."""
from __future__ import annotations

import re
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.accounts import Account, as_session

from ..factories import Scene

#: The odd values each query parameter is sent, by what they try.
ODD = {
    "early date": "0001-01-01T00:00:00+05:00",
    "late date": "9999-12-31T23:59:59-05:00",
    "huge int": "9" * 30,
    "negative huge int": "-" + "9" * 30,
    "beyond int64": "9223372036854775808",
    "NaN": "NaN",
    "inf": "inf",
    "-inf": "-Infinity",
    "huge float": "1e999",
    "NUL": "a\x00b",
    "empty": "",
    "long": "x" * 5000,
    "format chars": "\u202e\u200b\ufeff",
}


@pytest.fixture
def lenient(app: FastAPI, accounts: dict[str, Account]):
    """The admin's browser session on a client that answers a server error as the 500 it is (no raise)."""
    with TestClient(app, raise_server_exceptions=False) as c:
        yield as_session(c, accounts["admin"])


def _operations(app: FastAPI) -> list[tuple[str, str, list[str]]]:
    """(method, path, query parameter names) of every operation that takes query parameters."""
    out = []
    for path, item in app.openapi()["paths"].items():
        for method, op in item.items():
            names = [p["name"] for p in op.get("parameters", []) if p.get("in") == "query"]
            if names:
                out.append((method.upper(), path, names))
    return out


def test_every_query_parameter_answers_odd_values_with_a_4xx_never_a_500(app: FastAPI, lenient: TestClient,
                                                                        scene: Scene) -> None:
    ids = {"system_id": scene.system_id, "frame_id": scene.frame_ids[0]}
    failures: list[str] = []
    sent = 0
    for method, path, names in _operations(app):
        url = re.sub(r"\{(\w+)\}", lambda m: str(ids.get(m.group(1), 1)), path)
        for name in names:
            for what, value in ODD.items():
                params: Any = {name: value}
                answer = lenient.request(method, url, params=params)
                sent += 1
                if answer.status_code >= 500:
                    failures.append(f"{method} {path}?{name}= {what}: {answer.status_code} {answer.text[:200]}")
                elif method == "GET" and answer.status_code == 422 and name not in answer.text:
                    failures.append(f"{method} {path}?{name}= {what}: 422 not naming {name}: {answer.text[:200]}")
            answer = lenient.request(method, f"{url}?{name}=%ED%A0%80")  # a lone surrogate's UTF-8: no text
            if answer.status_code >= 500:
                failures.append(f"{method} {path}?{name}= a surrogate: {answer.status_code} {answer.text[:200]}")
            answer = lenient.request(method, url, params=[(name, "1"), (name, "2")])  # repeated
            if answer.status_code >= 500:
                failures.append(f"{method} {path}?{name} repeated: {answer.status_code} {answer.text[:200]}")
    assert sent > 200
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("route", ["/api/stats/annotators", "/api/audit"])
@pytest.mark.parametrize(("field", "value", "words"), [("since", "0001-01-01T00:00:00+05:00", "outside the years"),
                                                       ("until", "9999-12-31T23:59:59-05:00", "outside the years"),
                                                       ("since", "-8", "not an ISO 8601 time"),
                                                       ("until", "1700000000", "not an ISO 8601 time")])
def test_a_time_that_is_no_date_of_the_years_in_utc_is_422_naming_the_field(lenient: TestClient, route: str,
                                                                            field: str, value: str,
                                                                            words: str) -> None:
    """Was: 500 (the conversion to UTC overflowed); then 200 for a number, which pydantic's lax mode reads as seconds
    since 1970 where the OpenAPI document promises an ISO 8601 ``date-time`` (schemathesis found ``since=-8``)."""
    answer = lenient.get(route, params={field: value})
    assert answer.status_code == 422, answer.text
    [error] = answer.json()["detail"]
    assert error["loc"] == ["query", field] and words in error["msg"], error
    fine = lenient.get(route, params={field: value.replace("0001", "0002").replace("9999", "9998")
                                      .replace("-8", "1970-01-01").replace("1700000000", "2023-11-14")})
    assert fine.status_code == 200, fine.text
