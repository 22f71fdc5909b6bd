"""The releases scenario walked against a running server (``v3d serve --demo``), as its users would: five systems
accepted, release ``v1.0`` (201, then 409 for the name again), its SoccerNet-v3D export job naming it in
``GameMetadata.v3d_release``, a released ball moved 8 px and accepted again, one rejected, one more accepted,
release ``v1.1``, the diff ``v1.0`` -> ``v1.1``, ``v1.0`` exported again and compared byte for byte, both listed.

Usage (the demo's account logs in from a loopback address only)::

    V3D_DATABASE_URL=sqlite:////tmp/walk.sqlite3 v3d serve --demo --port 8765 &
    .venv/bin/python benchmarks/release_walk.py [--url http://127.0.0.1:8765]
"""
from __future__ import annotations

import argparse
import hashlib
import io
import json
import sys
import time
import zipfile
from typing import Any, Optional

import httpx


class Walk:
    """The demo admin's session on the server at ``url``."""

    def __init__(self, url: str) -> None:
        self.c = httpx.Client(base_url=url, timeout=120)
        login = self.c.post("/api/auth/login", json={"name": "demo", "password": "demo"})
        login.raise_for_status()
        self.headers = {"X-CSRF-Token": login.json()["csrf_token"]}

    def decide(self, system_id: int, status: str) -> None:
        etag = self.c.get(f"/api/systems/{system_id}").headers["etag"]
        answer = self.c.post(f"/api/systems/{system_id}/review", json={"status": status, "comment": ""},
                             headers={**self.headers, "If-Match": etag})
        assert answer.status_code == 200, answer.text

    def release(self, name: str) -> httpx.Response:
        return self.c.post("/api/releases", json={"name": name}, headers=self.headers)

    def export(self, name: str) -> bytes:
        job = self.c.post("/api/exports/soccernet-v3d", json={"release": name}, headers=self.headers).json()
        while (state := self.c.get(job["url"]).json())["state"] not in ("done", "failed"):
            time.sleep(0.5)
        assert state["state"] == "done", state
        return self.c.get(state["result_url"]).content

    def move_ball(self, system_id: int, dx: float) -> int:
        view = next(v for v in self.c.get(f"/api/systems/{system_id}").json()["views"]
                    if v.get("ball") and v["ball"].get("box"))
        box = view["ball"]["box"]
        moved = self.c.patch(f"/api/frames/{view['frame_id']}/ball",
                             json={"box": [box[0] + dx, box[1], box[2] + dx, box[3]]}, headers=self.headers)
        return moved.status_code


def run(url: str) -> dict[str, Any]:
    """The walk (module docstring); what it saw."""
    w = Walk(url)
    ids = [s["id"] for s in w.c.get("/api/systems", params={"limit": 20, "sort": "name",
                                                           "kind": "soccernet-v3"}).json()["items"]][:6]
    for sid in ids[:5]:
        w.decide(sid, "accepted")
    v10 = w.release("v1.0")
    out: dict[str, Any] = {"v1.0": [v10.status_code, v10.json()], "taken": w.release("v1.0").status_code}
    first = w.export("v1.0")
    with zipfile.ZipFile(io.BytesIO(first)) as zf:
        out["named"] = [json.loads(zf.read(n))["GameMetadata"]["v3d_release"] for n in zf.namelist()
                        if n.endswith("Labels-v3D.json")]
    out["move"] = w.move_ball(ids[0], 8.0)
    w.decide(ids[0], "accepted")
    w.decide(ids[1], "rejected")
    w.decide(ids[5], "accepted")
    v11 = w.release("v1.1").json()
    out["v1.1"] = {"systems": v11["systems"], "hash": v11["hash"]}
    d = w.c.get("/api/releases/v1.0/diff/v1.1").json()
    out["diff"] = {"added": [x["system_id"] for x in d["added"]], "removed": [x["system_id"] for x in d["removed"]],
                   "changed": [(x["system_id"], x["ball3d_moved_m"]) for x in d["changed"]],
                   "expected": {"added": [ids[5]], "removed": [ids[1]], "changed": [ids[0]]}}
    again = w.export("v1.0")
    out["re-export identical"] = again == first
    out["export sha256"] = hashlib.sha256(first).hexdigest()
    out["listed"] = [r["name"] for r in w.c.get("/api/releases").json()["items"]]
    return out


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--url", default="http://127.0.0.1:8765", help="The running server (loopback).")
    print(json.dumps(run(p.parse_args(argv).url), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
