"""The client package (``clients/python``) installs and imports on a script's machine without the server's science:
it requires httpx and pydantic only (at the floors v3d requires them, so that v3d, which ships the client's sources,
adds no package beyond its locks), its import loads neither ``app`` nor numpy nor scipy, nothing it requires needs
them, and its version is the server's."""
from __future__ import annotations

import subprocess
import sys
import tomllib
from importlib import metadata

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

import app
import v3d_client
from app.core.paths import PROJECT_ROOT

CLIENT = PROJECT_ROOT / "clients" / "python"
SCIENCE = {"numpy", "scipy", "numba", "opencv-python-headless"}


def _project(path) -> dict:
    return tomllib.loads(path.read_text(encoding="utf-8"))["project"]


def test_the_client_requires_httpx_and_pydantic_at_the_servers_floors() -> None:
    client = {canonicalize_name(r.name): r.specifier for r in map(Requirement, _project(CLIENT / "pyproject.toml")
                                                                 ["dependencies"])}
    server = {canonicalize_name(r.name): r.specifier for r in map(Requirement, _project(PROJECT_ROOT / "pyproject.toml")
                                                                 ["dependencies"])}
    assert set(client) == {"httpx", "pydantic"}
    assert all(client[name] == server[name] for name in client), (client, server)


def test_nothing_the_client_requires_needs_numpy_or_scipy() -> None:
    """The installed closure of the client's requirements (their own requirements, recursively, as installed here)."""
    seen: set[str] = set()
    todo = ["httpx", "pydantic"]
    while todo:
        name = canonicalize_name(todo.pop())
        if name in seen:
            continue
        seen.add(name)
        for line in metadata.requires(name) or []:
            req = Requirement(line)
            if req.marker is None or req.marker.evaluate({"extra": ""}):
                todo.append(req.name)
    assert "pydantic-core" in seen and "httpcore" in seen  # the walk reached their own requirements
    assert not seen & SCIENCE, seen & SCIENCE


def test_importing_the_client_loads_neither_the_server_nor_numpy() -> None:
    code = ("import sys, v3d_client, v3d_client.progress; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('app', 'numpy', 'scipy', 'sqlalchemy')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=CLIENT)
    assert out.stdout.strip() == "[]", out.stdout


def test_the_client_is_versioned_with_the_server() -> None:
    assert v3d_client.__version__ == app.__version__ == _project(PROJECT_ROOT / "pyproject.toml")["version"]
    assert 'version = {attr = "v3d_client.version.__version__"}' in (CLIENT / "pyproject.toml").read_text()
