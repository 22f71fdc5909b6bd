"""The team's loop through a running server (the Done-when of the team's loop, against ``v3d serve --demo``).

Usage: ``v3d serve --demo --port 8765`` on a fresh database; make a reviewer and two annotators with API tokens::

    for u in rev:reviewer ana:annotator bob:annotator; do
      echo pw-"${u%%:*}"-12345 | v3d users add "${u%%:*}" --role "${u##*:}" --password-stdin
    done
    python benchmarks/team_walk.py http://127.0.0.1:8765 "$(v3d users token rev)" "$(v3d users token ana)" \
        "$(v3d users token bob)"

Prints each step's status and exits 1 at the first answer that is not the expected one.
"""
from __future__ import annotations

import sys

import httpx


def main(base: str, rev_token: str, ana_token: str, bob_token: str) -> None:
    def client(token: str) -> httpx.Client:
        return httpx.Client(base_url=base, headers={"Authorization": f"Bearer {token}"}, timeout=60)

    rev, ana, bob = client(rev_token), client(ana_token), client(bob_token)

    def check(what: str, ok: bool, detail: object = "") -> None:
        print(f"{'ok ' if ok else 'NO '} {what} {detail}")
        if not ok:
            sys.exit(1)

    sid = rev.get("/api/systems", params={"limit": 1, "sort": "name", "status": "pending"}).json()["items"][0]["id"]
    page = ana.get(f"/api/systems/{sid}").json()
    view = next(v for v in page["views"] if v.get("ball") and v["ball"].get("box"))
    box = view["ball"]["box"]
    moved = ana.patch(f"/api/frames/{view['frame_id']}/ball", headers={"If-Match": view["etag"]},
                      json={"box": [box[0] + 4, box[1], box[2] + 4, box[3]]})
    check("ana moves a ball label", moved.status_code == 200, moved.status_code)
    pinned = rev.post(f"/api/systems/{sid}/comments", json={"frame_id": view["frame_id"], "point": [400, 300],
                                                             "text": "the box sits on the shadow"})
    check("rev pins a comment on the view", pinned.status_code == 201, pinned.json())
    etag = rev.get(f"/api/systems/{sid}").headers["etag"]
    sent = rev.post(f"/api/systems/{sid}/review", headers={"If-Match": etag},
                    json={"status": "needs_fix", "comment": "see the pinned comment"})
    check("rev marks it needs fix; it goes to ana", sent.status_code == 200 and sent.json().get("returned_to") == "ana",
          sent.json().get("handoff"))
    mine = [r["id"] for r in ana.get("/api/systems", params={"assignee": "me", "status": "needs_fix"}).json()["items"]]
    check("ana finds it under assignee=me&status=needs_fix", sid in mine, mine)
    comments = ana.get(f"/api/systems/{sid}/comments").json()["items"]
    check("ana reads the comment", [c["text"] for c in comments] == ["the box sits on the shadow"])
    etag = bob.get(f"/api/systems/{sid}").headers["etag"]
    other = bob.post(f"/api/systems/{sid}/review", headers={"If-Match": etag}, json={"status": "fixed"})
    check("bob's fixed is 403", other.status_code == 403, other.status_code)
    accepted = ana.post(f"/api/systems/{sid}/review", headers={"If-Match": etag}, json={"status": "accepted"})
    check("ana's accepted is 403", accepted.status_code == 403, accepted.status_code)
    page = ana.get(f"/api/systems/{sid}").json()
    view = next(v for v in page["views"] if v["frame_id"] == view["frame_id"])
    box = view["ball"]["box"]
    again = ana.patch(f"/api/frames/{view['frame_id']}/ball", headers={"If-Match": view["etag"]},
                      json={"box": [box[0] - 3, box[1], box[2] - 3, box[3]]})
    check("ana moves the label again", again.status_code == 200, again.status_code)
    resolved = ana.post(f"/api/comments/{pinned.json()['id']}/resolve")
    check("ana resolves the comment", resolved.status_code == 200 and resolved.json()["resolved"] is True)
    etag = ana.get(f"/api/systems/{sid}").headers["etag"]
    fixed = ana.post(f"/api/systems/{sid}/review", headers={"If-Match": etag}, json={"status": "fixed"})
    check("ana sends fixed", fixed.status_code == 200, fixed.status_code)
    back = [r["id"] for r in rev.get("/api/systems", params={"assignee": "me", "status": "fixed"}).json()["items"]]
    check("rev finds it under assignee=me&status=fixed", sid in back, back)
    stats = {r["name"]: r for r in rev.get("/api/stats/annotators").json()["items"]}
    check("ana's figures: >= 2 edits, 1 needs fix received",
          stats["ana"]["edits"] >= 2 and stats["ana"]["needs_fix_received"] == 1,
          {k: stats["ana"][k] for k in ("edits", "needs_fix_received", "median_label_distance_px")})
    csv = rev.get("/api/stats/annotators", params={"format": "csv"})
    check("the CSV answers text/csv", csv.headers["content-type"].startswith("text/csv"), csv.text.splitlines()[0])


if __name__ == "__main__":
    main(*sys.argv[1:5])
