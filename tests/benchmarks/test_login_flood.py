"""``benchmarks/login_flood.py`` against the real server (a subprocess): wrong passwords, many at once (24, 8 at a
time, with a 2 MB body in CI's suite; the benchmark's 60, 16 at a time, with 20 MB in the slow tier): the first 10
are 401 and the rest 429 (the per-name limit), the right password is then 429 with Retry-After, the health probe
kept answering 200 throughout; the large JSON body is 413."""
from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import login_flood
from tests.conftest import sizes


@pytest.mark.parametrize("size", sizes((24, 8, 2.0), (60, 16, 20.0)))
def test_a_login_flood_is_cut_at_the_limit_and_the_server_keeps_answering(size: tuple[int, int, float],
                                                                         tmp_path: Path) -> None:
    attempts, concurrency, body_mb = size
    out = login_flood.run(attempts=attempts, concurrency=concurrency, body_mb=body_mb, workdir=tmp_path)
    flood, body = out["flood"], out["body"]
    assert flood["statuses"] == {401: 10, 429: attempts - 10}
    assert flood["right_password_after"] == 429 and 1 <= int(flood["retry_after_s"]) <= 300
    assert set(flood["health_statuses"]) == {200} and flood["health_during_ms"]["n"] >= 1
    assert body["status"] == 413
