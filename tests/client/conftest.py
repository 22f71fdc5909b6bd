"""One served demo per test module of the client (``served_demo``): ``v3d serve --demo``'s database (the demo
imported) with one account per role, served by uvicorn in a thread with its job runner, and the raw REST API beside
it (``raw``: plain httpx with a role's token) through which the tests check what the client, the examples and the
command line did."""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest

from app.core.config import Settings
from tests.accounts import Account, make_accounts
from tests.conftest import copy_sqlite
from tests.live_server import serve_app


@dataclass
class ServedDemo:
    """A served demo: its URL, its accounts by role, its settings."""

    url: str
    accounts: dict[str, Account]
    settings: Settings

    def raw(self, role: str = "admin") -> httpx.Client:
        """Plain httpx on the server with ``role``'s token (the tests' own view of the API)."""
        return httpx.Client(base_url=self.url, headers=self.accounts[role].bearer, timeout=120)

    def token(self, role: str = "admin") -> str:
        """``role``'s API token."""
        return self.accounts[role].token


@contextmanager
def serve_demo(root: Path, demo_template: Path, **settings: Any) -> Iterator[ServedDemo]:
    """The demo as ``v3d serve --demo`` loads it (a copy of ``tests.conftest.demo_template``), with one account per
    role, served from ``root`` until the block ends (``settings``: more of the server's settings)."""
    from app.main import create_app

    chosen = Settings(_env_file=None, database_url=copy_sqlite(demo_template, root / "v3d.sqlite3"),
                      calibration_workers=1, jobs_dir=root / "jobs", job_runner=True, **settings)
    accounts = make_accounts(chosen.database_url, login=False)
    with serve_app(create_app(chosen)) as url:
        yield ServedDemo(url, accounts, chosen)


@pytest.fixture(scope="module")
def served_demo(tmp_path_factory: pytest.TempPathFactory, demo_template: Path) -> Iterator[ServedDemo]:
    """The module's served demo (made once per module)."""
    with serve_demo(tmp_path_factory.mktemp("served-demo"), demo_template) as served:
        yield served


def page_through(raw: httpx.Client, path: str, **params: object) -> list[dict]:
    """Every item of a list the raw API pages by offset (``limit`` 500)."""
    items: list[dict] = []
    while True:
        answer = raw.get(path, params={**params, "limit": 500, "offset": len(items)})
        assert answer.status_code == 200, answer.text
        body = answer.json()
        items += body["items"]
        if not body["items"] or len(items) >= body["total"]:
            return items


def zip_of(folder: Path, target: Path) -> Path:
    """``folder``'s files in the zip ``target``, named relative to it (written by the test, not by the client)."""
    import zipfile

    with zipfile.ZipFile(target, "w") as zf:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(folder).as_posix())
    return target
