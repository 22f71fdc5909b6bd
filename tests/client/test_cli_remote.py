"""``v3d --server URL`` (``V3D_URL`` and ``V3D_TOKEN``): the command line driving a served demo through the client,
from a working folder that holds no database and in which nothing but the OUT given is written; what each command did
is checked through the raw REST API, a release's export against the raw download and against the same command run on
the server's database locally (``release export`` and ``jobs wait`` are new in both places). A refusal of the server
(401, 403, 409, 422) exits 2 with the server's words; a command that runs only on the server's machine is refused.
"""
from __future__ import annotations

import io
import json
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from app.cli import _root
from tests.client.conftest import ServedDemo, page_through

pytestmark = [pytest.mark.shared]
DEV = ("data", "synthetic", "soccernet-v3-dev")


@pytest.fixture(scope="module")
def cli() -> typer.Typer:
    """The ``v3d`` command with every command registered, as ``app.cli.main`` registers them."""
    from app.cli import (  # noqa: F401  # each module registers its commands
        datasets,
        detectors,
        doubts,
        jobs,
        predictions,
        releases,
        serve,
        users,
    )
    from app.cli.exports import register_remaining_exports

    register_remaining_exports()
    return _root.cli


@pytest.fixture
def elsewhere(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A working folder of its own, and a local database URL that must stay untouched (no file made)."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    monkeypatch.setenv("V3D_DATABASE_URL", f"sqlite:///{tmp_path / 'never.sqlite3'}")
    yield work
    assert not (tmp_path / "never.sqlite3").exists()


def v3d(cli: typer.Typer, served: ServedDemo, *args: str, role: str = "admin", token: str | None = None,
        stdin: str | None = None) -> tuple[int, str]:
    """Run ``v3d --server URL ARGS`` with ``role``'s token; (exit status, standard output and error)."""
    env = {"V3D_TOKEN": token if token is not None else served.token(role), "V3D_URL": ""}
    result = CliRunner().invoke(cli, ["--server", served.url, *args], env=env, input=stdin)
    return result.exit_code, result.output


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _zip_files(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}


def test_import_export_and_a_release_from_another_folder(cli: typer.Typer, served_demo: ServedDemo, shared_dir: Path,
                                                         elsewhere: Path) -> None:
    raw = served_demo.raw()
    games_before = len(raw.get("/api/games").json())
    code, out = v3d(cli, served_demo, "import", "soccernet-v3", str(shared_dir.joinpath(*DEV)))
    assert code == 0, out
    assert "2 game(s), 40 system(s), 105 frame(s)" in out and "uploading" in out
    assert len(raw.get("/api/games").json()) == games_before + 2

    for system in page_through(raw, "/api/systems", doubt="none")[:5]:  # something accepted to export and release
        etag = raw.get(f"/api/systems/{system['id']}").headers["etag"]
        assert raw.post(f"/api/systems/{system['id']}/review", json={"status": "accepted"},
                        headers={"If-Match": etag}).status_code == 200
    code, out = v3d(cli, served_demo, "export", "soccernet-v3d", "now", "--no-images")
    assert code == 0, out
    direct = raw.get("/api/exports/soccernet-v3d", params={"images": "false"})
    assert _files(elsewhere / "now").keys() == _zip_files(direct.content).keys()
    assert (elsewhere / "now" / "SNv3D.csv").read_bytes() == _zip_files(direct.content)["SNv3D.csv"]

    code, out = v3d(cli, served_demo, "release", "create", "team-1", "--note", "from a laptop")
    assert code == 0, out
    made = json.loads(out)
    assert made == {k: v for k, v in raw.get("/api/releases/team-1").json().items() if k != "made_by"}
    assert made["systems"] == 5

    code, out = v3d(cli, served_demo, "release", "export", "team-1", "soccernet-v3d", "team-1")
    assert code == 0, out
    release_zip = raw.get("/api/exports/soccernet-v3d", params={"release": "team-1"}).content
    assert _files(elsewhere / "team-1") == _zip_files(release_zip)
    assert sorted(p.name for p in elsewhere.iterdir()) == ["now", "team-1"]

    code, out = v3d(cli, served_demo, "release", "list")
    assert code == 0 and out.split("\t")[0] == "team-1" and made["hash"] in out
    code, out = v3d(cli, served_demo, "release", "diff", "team-1", "team-1")
    assert code == 0 and json.loads(out)["unchanged"] == 5


def test_the_local_release_export_and_job_wait_write_what_the_remote_ones_do(cli: typer.Typer, served_demo: ServedDemo,
                                                                             tmp_path: Path) -> None:
    """Without --server the new commands read the server's database itself, with the same result."""
    local = ["--database-url", served_demo.settings.database_url]
    result = CliRunner().invoke(cli, ["release", "export", "team-1", "soccernet-v3d", str(tmp_path / "here"), *local],
                                env={"V3D_URL": ""})
    assert result.exit_code == 0, result.output
    release_zip = served_demo.raw().get("/api/exports/soccernet-v3d", params={"release": "team-1"}).content
    assert _files(tmp_path / "here") == _zip_files(release_zip)
    job = served_demo.raw().get("/api/jobs", params={"kind": "import"}).json()["items"][0]
    result = CliRunner().invoke(cli, ["jobs", "wait", str(job["id"]), *local], env={"V3D_URL": ""})
    assert result.exit_code == 0, result.output
    assert json.loads(result.output[result.output.index("{"):]) == job["result"]


def test_users_jobs_and_stats_on_the_server(cli: typer.Typer, served_demo: ServedDemo, elsewhere: Path) -> None:
    raw = served_demo.raw()
    code, out = v3d(cli, served_demo, "users", "add", "laptop-ana", "--role", "annotator", "--password-stdin",
                    stdin="a long enough password\n")
    assert code == 0, out
    token = out.strip().splitlines()[-1]
    assert served_demo.raw().get("/api/auth/me", headers={"Authorization": f"Bearer {token}"}).json()["name"] == \
        "laptop-ana"
    code, out = v3d(cli, served_demo, "users", "list")
    assert code == 0 and "laptop-ana" in out and "test-reviewer" in out
    code, out = v3d(cli, served_demo, "users", "disable", "laptop-ana")
    assert code == 0, out
    assert next(u for u in raw.get("/api/users").json() if u["name"] == "laptop-ana")["disabled"] is True

    newest = raw.get("/api/jobs").json()
    code, out = v3d(cli, served_demo, "jobs", "list", "--limit", "3")
    assert code == 0 and out.strip().splitlines()[-1] == f"{min(3, newest['total'])} of {newest['total']} job(s)"
    assert out.split()[0] == str(newest["items"][0]["id"])
    code, out = v3d(cli, served_demo, "jobs", "wait", str(newest["items"][0]["id"]))
    assert code == 0 and json.loads(out[out.index("{"):]) == newest["items"][0]["result"]

    stats = raw.get("/api/stats").json()
    code, out = v3d(cli, served_demo, "stats")
    kind, figures = next(iter(stats["kinds"].items()))
    assert code == 0 and f"{kind}: {figures['systems']} system(s), {figures['images']} image(s)" in out
    code, out = v3d(cli, served_demo, "stats", "annotators", role="reviewer")
    assert code == 0, out
    assert list(elsewhere.iterdir()) == []


def test_a_refusal_exits_2_with_the_servers_words(cli: typer.Typer, served_demo: ServedDemo, elsewhere: Path) -> None:
    raw = served_demo.raw()
    cases = [  # the same refusal asked of the raw API, then of the command
        ("admin", "not-a-token", ("release", "list"), ("GET", "/api/releases", None)),  # 401
        ("annotator", None, ("release", "create", "by-an-annotator"), ("POST", "/api/releases",
                                                                       {"name": "by-an-annotator"})),  # 403
        ("admin", None, ("release", "create", "team-1"), ("POST", "/api/releases", {"name": "team-1"})),  # 409
        ("admin", None, ("users", "add", "x", "--role", "owner", "--password-stdin"),
         ("POST", "/api/users", {"name": "x", "role": "owner", "password": "pw pw pw pw"})),  # 422
    ]
    for role, token, args, (method, path, body) in cases:
        headers = {"Authorization": f"Bearer {token}"} if token else served_demo.accounts[role].bearer
        answer = raw.request(method, path, json=body, headers=headers)
        detail = answer.json()["detail"]
        words = detail if isinstance(detail, str) else detail[0]["msg"]
        code, out = v3d(cli, served_demo, *args, role=role, token=token, stdin="pw pw pw pw\n")
        assert code == 2, out
        assert f"Error: {answer.status_code}: " in out and words in out, (out, words)
    assert list(elsewhere.iterdir()) == []


def test_a_command_of_the_servers_machine_only_is_refused(cli: typer.Typer, served_demo: ServedDemo,
                                                         elsewhere: Path) -> None:
    for args in (("doubts",), ("users", "token", "test-admin"), ("import", "issia", "somewhere")):
        code, out = v3d(cli, served_demo, *args)
        assert code == 2 and "runs on the server's machine only" in out, out
