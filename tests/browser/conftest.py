"""Fixtures of the browser tests: the real v3d server on a free port, over a migrated temporary SQLite
database seeded with the demo dataset and two users (``tests/accounts.py``: ``test-admin``,
``test-annotator``), and a headless Debian Chromium driven by Playwright. ``page`` is the admin's
browser, logged in once per module through the login page (where the queue sends a visitor).

What costs seconds is made once per test session (per pytest-xdist worker): Chromium (``chromium``, of
``tests/conftest.py``; each test sees it as ``browser``, which records its contexts' traces), and each seeded database
(:class:`SeededDatabases`: the demo imported and calibrated, its accounts made), which every module then copies
into a file of its own, so that a module's edits reach no other module."""
from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.accounts import Account, make_accounts
from tests.browser.support import import_into_new_database, log_in
from tests.live_server import serve_app

#: Screenshots of the walk (gitignored), for people to look at.
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"
#: The accounts every seeded database holds.
SEEDED_ROLES = ("annotator", "admin")


class SeededDatabases:
    """SQLite databases built once per test session by name, each copied for every module that asks for it.

    A copy names the same dataset folders as its template (the frames' images are read, never written, by the
    pages) and holds the same accounts, whose passwords and tokens therefore work on every copy."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self._templates: dict[str, tuple[object, dict[str, Account]]] = {}
        #: database URL of each copy -> the accounts it holds
        self.accounts: dict[str, dict[str, Account]] = {}

    def copy(self, name: str, build: Callable[[object], None], into: Path, data_root: Path | None = None):
        """Settings of a new copy in ``into`` of the database ``name``; the first call builds it with
        ``build(settings)`` (a new database: migrate and fill it), then makes its accounts. ``data_root``: the
        folder its datasets are named under (the test session's temporary folder by default)."""
        from app.core.config import Settings

        if name not in self._templates:
            folder = self.root / name
            folder.mkdir(parents=True)
            settings = Settings(database_url=f"sqlite:///{folder / 'template.sqlite3'}", calibration_workers=1,
                                data_root=data_root or self.root.parent)
            build(settings)
            self._templates[name] = (settings, make_accounts(settings.database_url, login=False, roles=SEEDED_ROLES))
        template, accounts = self._templates[name]
        target = into / f"{name}.sqlite3"
        with sqlite3.connect(_sqlite_path(template)) as source, sqlite3.connect(target) as copy:
            source.backup(copy)  # the write-ahead log's pages included
        settings = template.model_copy(update={"database_url": f"sqlite:///{target}"})
        self.accounts[settings.database_url] = accounts
        return settings


def _sqlite_path(settings) -> str:
    import sqlalchemy as sa

    return str(sa.make_url(settings.database_url).database)


@pytest.fixture(scope="session")
def seeded_databases(tmp_path_factory: pytest.TempPathFactory) -> SeededDatabases:
    """The session's :class:`SeededDatabases` (in this worker's temporary folder, which is the data root)."""
    return SeededDatabases(tmp_path_factory.mktemp("seeded"))


def build_demo_database(settings) -> None:
    """The demo dataset through the SoccerNet-v3 importer, as a user would (``v3d demo`` then ``v3d import``), then
    the calibration-only frames of :func:`_calibration_only_folder` through the SoccerNet-calibration importer."""
    from app.demo import generate_demo_dataset
    from app.services.transfer.importing import import_sn_calibration

    root = Path(_sqlite_path(settings)).parent
    dataset = generate_demo_dataset(root / "demo")
    calibration_only = _calibration_only_folder(dataset, root / "calibration-only")
    import_into_new_database(settings, dataset, then=lambda session: import_sn_calibration(
        session, calibration_only, settings, width=CALIB_ONLY_SIZE[0], height=CALIB_ONLY_SIZE[1]))


@pytest.fixture(scope="module")
def seeded_settings(seeded_databases: SeededDatabases, tmp_path_factory: pytest.TempPathFactory):
    """Settings of this module's copy of the demo database (:func:`build_demo_database`)."""
    return seeded_databases.copy("demo", build_demo_database, tmp_path_factory.mktemp("ui"))


#: Size of the calibration-only frames (no image: the UI draws on a blank canvas of this size).
CALIB_ONLY_SIZE = (1920, 1080)


def _calibration_only_folder(dataset: Path, out: Path) -> Path:
    """A SoccerNet-calibration folder (normalised points, no images) made of the demo's first
    1920x1080 action's field lines: frames that exist only as annotations, like the calibration
    challenge's test set."""
    labels = json.loads(next(dataset.rglob("Labels-v3.json")).read_text())
    w, h = CALIB_ONLY_SIZE
    name, action = next((n, a) for n, a in labels["actions"].items()
                        if (a["imageMetadata"]["width"], a["imageMetadata"]["height"]) == (w, h))
    frame = {}
    for line in action["lines"]:
        xy = line["points"]
        frame.setdefault(line["class"], []).extend(
            {"x": x / (w - 1), "y": y / (h - 1)} for x, y in zip(xy[0::2], xy[1::2], strict=False))
    out.mkdir(parents=True)
    (out / f"{Path(name).stem}.json").write_text(json.dumps(frame))
    return out


@pytest.fixture(scope="module")
def server_url(seeded_settings) -> Iterator[str]:
    """Base URL of the real application (``create_app``) served by uvicorn in a thread."""
    from app.main import create_app

    app = create_app(seeded_settings)
    with serve_app(app) as url:
        yield url


@pytest.fixture(scope="module")
def accounts(seeded_settings, seeded_databases: SeededDatabases) -> dict[str, Account]:
    """An admin and an annotator of the seeded database (their passwords, no session yet): those of its template,
    or, for a database a module built itself, made now."""
    known = seeded_databases.accounts.get(seeded_settings.database_url)
    return known if known is not None else make_accounts(seeded_settings.database_url, login=False,
                                                         roles=SEEDED_ROLES)


@pytest.fixture(scope="module")
def admin_state(chromium, server_url, accounts) -> dict:
    """The browser state (cookies) of the admin logged in through the page: the queue sends an
    anonymous visitor to ``/login?next=/``, and the login sends them back."""
    context = chromium.new_context(base_url=server_url)
    try:
        p = context.new_page()
        p.goto("/")
        p.wait_for_url(f"{server_url}/login?next=%2F")
        log_in(p, accounts["admin"])
        p.wait_for_url(f"{server_url}/")
        return context.storage_state()
    finally:
        context.close()


def admin_page(browser, server_url: str, admin_state: dict, width: int, height: int) -> Iterator:
    """A ``width`` x ``height`` page of the logged-in admin (for a fixture to yield from); JavaScript errors on the
    page fail the test."""
    context = browser.new_context(viewport={"width": width, "height": height}, base_url=server_url,
                                  storage_state=admin_state)
    p = context.new_page()
    errors: list[str] = []
    p.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        yield p
    finally:
        context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"


@pytest.fixture
def page(browser, server_url, admin_state):
    """A 1440x900 page of the logged-in admin (:func:`admin_page`)."""
    yield from admin_page(browser, server_url, admin_state, 1440, 900)


@pytest.fixture(scope="session")
def artifacts() -> Path:
    ARTIFACTS.mkdir(exist_ok=True)
    return ARTIFACTS
