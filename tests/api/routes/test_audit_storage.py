"""The audit log stores a large state once, compressed (``app.services.audit.log.stored_state``, ``audit_states``):
each 2,000-point field-line edit stored its lines before and after whole in its entry (about 140 KB an edit at
full precision), so an annotator's edits grew the log by the size of two line sets each. ``GET /api/audit``, revert
and undo read the states as before."""
from __future__ import annotations

import json
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from benchmarks.edit_lock import dense_lines
from tests.api.factories import Scene

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def _stored_bytes(session: Session, entry_ids: list[int]) -> int:
    """Bytes the audit tables hold for the entries ``entry_ids``: their states inline (as text) and, where the
    database has them, the distinct stored states they name."""
    entries = sa.table("audit_entries", sa.column("id"), sa.column("before"), sa.column("after"))
    inline = session.execute(sa.select(
        sa.func.coalesce(sa.func.sum(sa.func.length(sa.cast(entries.c.before, sa.Text))), 0)
        + sa.func.coalesce(sa.func.sum(sa.func.length(sa.cast(entries.c.after, sa.Text))), 0))
        .where(entries.c.id.in_(entry_ids))).scalar_one()
    if "audit_states" not in sa.inspect(session.connection()).get_table_names():
        return int(inline)
    digests = session.execute(sa.text(
        "SELECT before_digest FROM audit_entries WHERE id IN ({ids}) UNION "
        "SELECT after_digest FROM audit_entries WHERE id IN ({ids})".format(ids=",".join(map(str, entry_ids)))
    )).scalars().all()
    states = sa.table("audit_states", sa.column("digest"), sa.column("body"))
    shared = session.execute(sa.select(sa.func.coalesce(sa.func.sum(sa.func.length(states.c.body)), 0))
                             .where(states.c.digest.in_([d for d in digests if d]))).scalar_one()
    return int(inline) + int(shared)


def _put(client: TestClient, fid: int, lines: dict[str, Any]) -> int:
    etag = client.get(f"/api/frames/{fid}").headers["ETag"]
    answer = client.put(f"/api/frames/{fid}/field-lines", json={"lines": lines}, headers={"If-Match": etag})
    assert answer.status_code == 200, answer.text
    return int(answer.headers["X-V3D-Audit-Entry"])


def test_line_edits_at_the_point_cap_store_each_state_once_compressed(client: TestClient, scene: Scene,
                                                                     db_session: Session) -> None:
    """Four 2,000-point line edits of one view, alternating two line sets at full precision: each edit's lines
    before and after were stored whole (here 4 x 2 line sets); now each distinct set once, compressed: less than a
    fifth of the bytes. The audit answers, and an undo, read them exactly as sent."""
    fid = scene.frame_ids[0]
    lines = client.get(f"/api/frames/{fid}").json()["field_lines"]
    a = dense_lines(lines, 2000, decimals=9)
    b = {c: [[[x + 0.25, y] for x, y in poly] for poly in polys] for c, polys in a.items()}
    ids = [_put(client, fid, state) for state in (a, b, a, b)]
    whole = 2 * len(ids) * len(json.dumps({"lines": a}, separators=(",", ":")))  # what storing every state whole takes
    stored = _stored_bytes(db_session, ids)
    assert stored < whole / 5, (stored, whole)

    items = {e["id"]: e for e in client.get("/api/audit", params={"frame_id": fid, "limit": 10}).json()["items"]}
    assert items[ids[1]]["before"] == {"lines": a} and items[ids[1]]["after"] == {"lines": b}
    assert items[ids[3]]["before"] == items[ids[2]]["after"] == {"lines": a}
    etag = client.get(f"/api/frames/{fid}").headers["ETag"]
    undo = client.post(f"/api/audit/{ids[3]}/undo", headers={"If-Match": etag})
    assert undo.status_code == 200, undo.text
    assert client.get(f"/api/frames/{fid}").json()["field_lines"] == a
    entry = client.get("/api/audit", params={"frame_id": fid, "limit": 1}).json()["items"][0]
    assert (entry["before"], entry["after"], entry["reverts_id"]) == ({"lines": b}, {"lines": a}, ids[3])


def test_small_states_stay_in_their_entry(client: TestClient, scene: Scene, db_session: Session) -> None:
    """A ball edit's state (a few dozen bytes) is kept in its entry: the audit's common reads need no other row."""
    from app.db.models import AuditEntry

    fid = scene.frame_ids[1]
    etag = client.get(f"/api/frames/{fid}").headers["ETag"]
    answer = client.patch(f"/api/frames/{fid}/ball", json={"box": [100.0, 100.0, 112.0, 112.0]},
                          headers={"If-Match": etag})
    assert answer.status_code == 200, answer.text
    entry = db_session.get(AuditEntry, int(answer.headers["X-V3D-Audit-Entry"]))
    assert entry is not None and entry.after_inline == {"ball": {"box": [100.0, 100.0, 112.0, 112.0], "point": None}}
    assert entry.after_digest is None and entry.before_digest is None
