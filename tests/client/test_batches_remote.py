"""Batches through the Python client and ``v3d --server URL batches ...``, against a served demo: a reviewer's batch
of the vouched systems with the server's random sample, the sample decided through the API, the rest accepted
(each audited with the batch's id), a refused batch exiting 2 with the server's words naming the system, an
annotator refused, and the same commands on the server's database locally."""
from __future__ import annotations

import json

import pytest
import sqlalchemy as sa
import typer
from typer.testing import CliRunner

from app.cli import _root
from tests.client.conftest import ServedDemo, page_through
from v3d_client import Client, Conflict, Forbidden


@pytest.fixture(scope="module")
def cli() -> typer.Typer:
    """The ``v3d`` command with the batches' commands registered."""
    from app.cli import batches  # noqa: F401  # registers its commands

    return _root.cli


def _vouch(served: ServedDemo, count: int) -> list[int]:
    """Make ``count`` pending systems of the demo the ones vouched for, the others the rule vouched for unconfirmed
    (the tier's computation is not this test's subject: the batch's systems are known)."""
    ids = [s["id"] for s in page_through(served.raw(), "/api/systems", status="pending", sort="name")][:count]
    engine = sa.create_engine(served.settings.database_url)
    with engine.begin() as conn:
        conn.execute(sa.text("UPDATE systems SET ball_evidence = 'unconfirmed' WHERE ball_evidence = 'vouched'"))
        conn.execute(sa.text("UPDATE systems SET ball_evidence = 'vouched' WHERE id IN ("
                             + ", ".join(str(int(i)) for i in ids) + ")"))
    engine.dispose()
    return sorted(ids)


def _decide(served: ServedDemo, system_id: int, status: str) -> None:
    raw = served.raw()
    etag = raw.get(f"/api/systems/{system_id}").headers["etag"]
    assert raw.post(f"/api/systems/{system_id}/review", json={"status": status},
                    headers={"If-Match": etag}).status_code == 200


def v3d(cli: typer.Typer, served: ServedDemo, *args: str, role: str = "reviewer") -> tuple[int, str]:
    result = CliRunner().invoke(cli, ["--server", served.url, *args],
                                env={"V3D_TOKEN": served.token(role), "V3D_URL": ""})
    return result.exit_code, result.output


def test_a_batch_through_the_client_and_the_command_line(cli: typer.Typer, served_demo: ServedDemo) -> None:
    vouched = _vouch(served_demo, 6)
    with Client(served_demo.url, served_demo.token("reviewer")) as client:
        batch = client.create_batch(confidence=0.75, max_wrong_share=0.5)
        assert batch.systems == vouched and len(batch.sample) == 2 and batch.state == "open"
        assert batch.plan == "if none of these 2 is wrong, you can be 75 % sure that at most 50 % of the 6 are"
        with pytest.raises(Conflict, match="not decided yet"):
            client.accept_batch(batch.id)
        for sid in batch.sample:
            client.decide(client.system(sid), "accepted")
        assert client.batch(batch.id).stops == []
        assert client.accept_batch(batch.id).accepted == 4
        entry = served_demo.raw().get("/api/audit", params={"system_id": next(
            i for i in vouched if i not in batch.sample), "limit": 1}).json()["items"][0]
        assert entry["after"]["review"]["batch_id"] == batch.id
        assert client.undo_batch(batch.id).undone == 4  # the sample stays as the person decided it
    pending = [i for i in vouched if i not in batch.sample]
    with Client(served_demo.url, served_demo.token("annotator")) as annotator, pytest.raises(Forbidden):
        annotator.create_batch()

    code, out = v3d(cli, served_demo, "batches", "create", "--confidence", "0.75", "--max-wrong-share", "0.5")
    assert code == 0, out
    made = json.loads(out)
    assert made["systems"] == pending and len(made["sample"]) == 2
    rejected, accepted = made["sample"]
    _decide(served_demo, rejected, "rejected")
    _decide(served_demo, accepted, "accepted")
    code, out = v3d(cli, served_demo, "batches", "accept", str(made["id"]))
    assert code == 2 and f"system {rejected} was rejected" in out
    code, out = v3d(cli, served_demo, "batches", "show", str(made["id"]))
    assert code == 0 and json.loads(out)["state"] == "refused"
    code, out = v3d(cli, served_demo, "batches", "create", role="annotator")
    assert code == 2 and "reviewer" in out

    # on the server's database itself, without --server: the same commands, as the machine's account
    local = ["--database-url", served_demo.settings.database_url]
    runner = CliRunner()
    result = runner.invoke(cli, ["batches", "create", "--confidence", "0.75", "--max-wrong-share", "0.5", *local],
                           env={"V3D_URL": ""})
    assert result.exit_code == 0, result.output
    here = json.loads(result.output)
    assert here["systems"] == [i for i in pending if i not in (rejected, accepted)] and len(here["sample"]) == 2
    assert here["created_by"].startswith("cli:") and here["plan"].startswith("all 2 are in the sample")
    result = runner.invoke(cli, ["batches", "accept", str(here["id"]), *local], env={"V3D_URL": ""})
    assert result.exit_code == 2 and "not decided yet" in result.output
