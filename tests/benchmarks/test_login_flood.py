"""A small version of ``benchmarks/login_flood.py`` against the real server (a subprocess): 24 wrong
passwords, 8 at once: the first 10 are 401 and the rest 429 (the per-name limit), the right password is then
429 with Retry-After, the health probe kept answering 200 throughout; a 2 MB JSON body is 413."""
from __future__ import annotations

from pathlib import Path

from benchmarks import login_flood


def test_a_login_flood_is_cut_at_the_limit_and_the_server_keeps_answering(tmp_path: Path) -> None:
    out = login_flood.run(attempts=24, concurrency=8, body_mb=2.0, workdir=tmp_path)
    flood, body = out["flood"], out["body"]
    assert flood["statuses"] == {401: 10, 429: 14}
    assert flood["right_password_after"] == 429 and 1 <= int(flood["retry_after_s"]) <= 300
    assert set(flood["health_statuses"]) == {200} and flood["health_during_ms"]["n"] >= 1
    assert body["status"] == 413
