"""Races of an annotator's "fixed" against a reviewer's accept, against a served demo: does a "fixed" ever undo an
accept it did not see?

A fresh database holding the demo (SQLite in a temporary folder, or a new database on the PostgreSQL server of
``--database-url``), served by a real ``v3d serve --demo`` (``benchmarks.edge_attacks.demo_server``: a subprocess,
one worker unless ``--workers``; ``--code DIR`` serves another checkout's code, e.g. ``/work/main`` for the figures
before a change). For each of ``--races`` (8) demo systems:

1. the annotator ``ana1`` (an API token) moves one view's ball label by 2 px (she is now its last label editor);
2. the reviewer ``rev`` (a token) marks the system needs fix: it is returned to ``ana1``;
3. the race: from two threads released together, ``ana1``'s browser session (a cookie and its CSRF token, as the
   page logs in; **no** ``If-Match``) sends ``fixed`` while ``rev`` accepts with the ``If-Match`` of the page he
   read after his needs fix.

Figures per race: both answers and the system's status afterwards. The one that counts: how many races end
"fixed" after both answered 200 (the accept silently undone; target 0). A ``fixed`` that lands first makes the accept
412 (its page no longer shows the system as it is), which is the guard working, not a lost accept.

Run::

    .venv/bin/python benchmarks/fixed_race.py [--races 8] [--code /work/main]
        [--database-url postgresql+psycopg://postgres@127.0.0.1:5432/test]
"""
from __future__ import annotations

import argparse
import json
import sys
import threading
from collections import Counter
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.edge_attacks import PASSWORD, demo_server
from benchmarks.load import fresh_database


def race_once(base: str, tokens: dict[str, str], session: Any, system_id: int) -> dict[str, Any]:
    """One race on system ``system_id`` (module docstring); ``session``: ``ana1``'s logged-in browser client."""
    import httpx

    def client(name: str) -> httpx.Client:
        return httpx.Client(base_url=base, timeout=120.0, headers={"Authorization": f"Bearer {tokens[name]}"})

    with client("ana1") as ana, client("rev") as rev:
        page = ana.get(f"/api/systems/{system_id}").json()
        view = next(v for v in page["views"] if v.get("ball") and v["ball"].get("box"))
        box = view["ball"]["box"]
        moved = ana.patch(f"/api/frames/{view['frame_id']}/ball", headers={"If-Match": view["etag"]},
                          json={"box": [box[0] + 2.0, box[1], box[2] + 2.0, box[3]]})
        assert moved.status_code == 200, moved.text
        etag = rev.get(f"/api/systems/{system_id}").headers["etag"]
        returned = rev.post(f"/api/systems/{system_id}/review", headers={"If-Match": etag},
                            json={"status": "needs_fix", "comment": "the box sits on the shadow"})
        assert returned.status_code == 200 and returned.json()["returned_to"] == "ana1", returned.text
        etag = rev.get(f"/api/systems/{system_id}").headers["etag"]  # the page the reviewer accepts from
        start, answers = threading.Barrier(2), {}

        def fixed() -> None:
            start.wait()
            answers["fixed"] = session.post(f"/api/systems/{system_id}/review",
                                            json={"status": "fixed", "comment": ""})

        def accept() -> None:
            start.wait()
            answers["accept"] = rev.post(f"/api/systems/{system_id}/review", headers={"If-Match": etag},
                                         json={"status": "accepted", "comment": ""})

        threads = [threading.Thread(target=fixed), threading.Thread(target=accept)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        status = rev.get(f"/api/systems/{system_id}").json()["review"]["status"]
    out = {"system": system_id, "fixed": answers["fixed"].status_code, "accept": answers["accept"].status_code,
           "status": status}
    if answers["fixed"].status_code not in (200,):
        out["fixed_says"] = answers["fixed"].json().get("detail")
    return out


def run(base: str, tokens: dict[str, str], races: int) -> dict[str, Any]:
    """``races`` races on the queue's first systems; their rows and the counts."""
    import httpx

    with httpx.Client(base_url=base, timeout=120.0) as listing:
        listing.headers["Authorization"] = f"Bearer {tokens['rev']}"
        ids = [row["id"] for row in listing.get("/api/systems", params={"limit": races}).json()["items"]]
    with httpx.Client(base_url=base, timeout=120.0) as session:
        logged = session.post("/api/auth/login", json={"name": "ana1", "password": PASSWORD})
        assert logged.status_code == 200, logged.text
        session.headers["X-CSRF-Token"] = logged.json()["csrf_token"]
        rows = [race_once(base, tokens, session, sid) for sid in ids]
    undone = sum(1 for r in rows if r["fixed"] == 200 and r["accept"] == 200 and r["status"] == "fixed")
    return {"races": len(rows), "accept_undone": undone,
            "outcomes": dict(Counter(f"fixed {r['fixed']} / accept {r['accept']} -> {r['status']}" for r in rows)),
            "rows": rows}


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--races", type=int, default=8)
    parser.add_argument("--code", type=Path, default=ROOT, help="the checkout whose code is served")
    parser.add_argument("--database-url", default=None, help="a PostgreSQL server (default: SQLite)")
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    with fresh_database(args.database_url) as url, demo_server(args.code.resolve(), url, args.workers) as (
            base, _pid, tokens):
        figures = run(base, tokens, args.races)
    print(json.dumps(figures, indent=1))
    print(f"{figures['accept_undone']} of {figures['races']} races ended 'fixed' after both answered 200 "
          f"(target 0): {figures['outcomes']}")
    return 0 if figures["accept_undone"] == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
