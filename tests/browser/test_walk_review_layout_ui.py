"""The queue page fits the window (Playwright, Chromium, the real server) over the demo and one game of the
labels-only ``soccernet-v3-dev-large`` set (../shared): its views without images, many without a camera, give the
rows with the most chips; and one row made to carry every chip the queue draws (its stored figures set so: every
doubt kind, views above tau, without a camera, below admission, without a ball, no 3D ball), the widest row the
page can be asked to draw. Skips without ../shared.
Screenshots in ``test-artifacts/walk-review/``."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import import_into_new_database, tid, wait_for_steady_layout

pytestmark = pytest.mark.browser

DEV_LARGE = Path(__file__).resolve().parents[3] / "shared" / "data" / "synthetic" / "soccernet-v3-dev-large"
#: The game of dev-large whose rows carry the most chips (no camera, below admission, few lines, rig position ...).
GAME = Path("synth_league_c") / "2031-2032" / "2031-10-15 - 18-00 Glenrock 0 - 1 Arden"


@pytest.fixture(scope="module")
def seeded_settings(tmp_path_factory: pytest.TempPathFactory):
    """The demo and one labels-only game of dev-large, each through the SoccerNet-v3 importer (as ``v3d import
    soccernet-v3`` does) into a new database."""
    labels = DEV_LARGE / GAME / "Labels-v3.json"
    if not labels.is_file():
        pytest.skip(f"{labels} not found: the labels-only set lives in ../shared")
    from app.core.config import Settings
    from app.demo import generate_demo_dataset

    root = tmp_path_factory.mktemp("layout")
    settings = Settings(database_url=f"sqlite:///{root / 'ui.sqlite3'}", calibration_workers=1,
                        data_root=tmp_path_factory.getbasetemp())
    tree = root / "labels-only"
    (tree / GAME).mkdir(parents=True)
    shutil.copyfile(labels, tree / GAME / "Labels-v3.json")  # a copy in the test's temporary folder only
    import_into_new_database(settings, generate_demo_dataset(root / "demo"), tree, then=_every_chip)
    return settings


def _every_chip(session) -> None:
    """The first system of the labels-only game shows every chip of a queue row (its stored queue figures)."""
    import sqlalchemy as sa

    from app.db.models import Game, System
    from app.geometry.doubts import INFO_KINDS, LABEL_KINDS

    system = session.scalars(sa.select(System).join(Game).where(Game.league == GAME.parts[0])
                             .order_by(System.id)).first()
    system.doubt_counts = {kind: 2 for kind in (*LABEL_KINDS, *INFO_KINDS)}
    system.label_doubts = 2 * len(LABEL_KINDS)
    system.views_total, system.views_calibrated, system.views_admitted, system.views_labelled = 6, 4, 2, 3
    system.views_above_tau = 2


def _chips(row: dict) -> int:
    return sum(1 for n in (row.get("doubt_counts") or {}).values() if n)


@pytest.mark.parametrize("size", [(1366, 768), (1920, 1080)], ids=["1366x768", "1920x1080"])
def test_the_queue_is_no_wider_than_the_window_and_every_chip_is_seen(page, artifacts, size):
    page.set_viewport_size({"width": size[0], "height": size[1]})
    rows = _api(page, "/api/systems?limit=500")["items"]
    assert max(_chips(r) for r in rows) >= 10
    page.goto("/?limit=500")
    page.locator(tid("queue-row")).first.wait_for()
    wait_for_steady_layout(page, f"{tid('queue-row')}, {tid('row-doubts')} .chip")  # what is measured and shot
    (artifacts / "walk-review").mkdir(exist_ok=True)
    page.screenshot(path=str(artifacts / f"walk-review/queue-{size[0]}x{size[1]}.png"))
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= size[0], f"the queue is {width} px wide in a {size[0]} px window"
    cut = page.eval_on_selector_all(f"{tid('row-doubts')} .chip", """(cs) => cs.filter((c) => {
      const r = c.getBoundingClientRect(); return r.right > innerWidth + 0.5 || r.left < 0;
    }).map((c) => c.textContent)""")
    assert cut == []
    # a cut game name keeps its whole name on hover
    game = page.locator("td.game").first
    assert game.get_attribute("title")
