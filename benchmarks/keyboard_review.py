"""A review of a whole queue by keyboard only (issue 16): time per system.

A reviewer opens the queue, presses Enter on its first row, and on every system decides each view's
calibration (``1``..``9`` selects the view, ``Shift+G`` accepts an admitted calibration, ``Shift+N`` marks one the
page says is not admitted, or a view without a camera, as needing a fix), then ``a`` accepts the system (and
``Enter`` when the accept guard lists open label doubts) and the page moves to the review pass's next pending
system, until the page says nothing pending is left in the pass. Nothing is clicked;
the page is read only to know when it is ready and what it says of each view's calibration.

:func:`review_by_keyboard` is the walk (``tests/browser/test_keyboard_review.py`` runs it on the 40 systems of
``soccernet-v3-dev`` and checks every decision through the API); :func:`main` imports a dataset into a fresh
SQLite database, serves it with ``v3d serve`` (``benchmarks.scale.Server``), logs a reviewer in through the
login page in Debian's Chromium (Playwright) and prints the time per system (median, p95, total) and the keys
pressed.

Usage (from the checkout)::

    nice -n 10 .venv/bin/python benchmarks/keyboard_review.py \\
        [--dataset ../shared/data/synthetic/soccernet-v3-dev] [--json out.json] [--headed]

Times include the server's answers (each decision a write with its audit entry, the system's decision, the
next system's page and images) on the same machine as the browser: a busy machine makes them pessimistic.
"""
from __future__ import annotations

import argparse
import json
import re
import secrets
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: The last decision of a review pass says so in its toast (static/js/system.js, LAST_OF_PASS).
LAST_SYSTEM_TEXT = "Nothing pending is left in this pass."
CHROMIUM = Path("/usr/bin/chromium")
TIMEOUT_MS = 60_000


@dataclass(frozen=True)
class SystemReview:
    """One system reviewed by keys: its id, views, the keys pressed, and the seconds from its page being
    ready to the next page being ready (or the last system's notice)."""

    system_id: int
    views: int
    keys: list[str]
    seconds: float


_READY = """(previous) => {
  if (document.body.classList.contains('loading')) return false;
  const views = [...document.querySelectorAll('[data-testid=view]')];
  if (!views.length || document.querySelectorAll('[data-testid=view-decisions]').length !== views.length) return false;
  return views[0].dataset.frameId !== previous;
}"""


def _first_frame(page) -> Optional[str]:
    return page.evaluate("() => document.querySelector('[data-testid=view]')?.dataset.frameId ?? null")


def _system_id(url: str) -> int:
    m = re.search(r"/systems/(\d+)", url)
    if not m:
        raise AssertionError(f"not a system page: {url}")
    return int(m.group(1))


def review_by_keyboard(page, queue_url: str, limit: Optional[int] = None) -> list[SystemReview]:
    """Review the queue at ``queue_url`` by keys only (module docstring) on a logged-in Playwright ``page``;
    answers one :class:`SystemReview` per system, in the queue's order. ``limit`` stops after that many
    systems. Raises ``AssertionError`` (or Playwright's timeout) when a page does not answer its keys within
    60 s."""
    page.goto(queue_url)
    page.locator("[data-testid=queue-row]").first.wait_for(timeout=TIMEOUT_MS)
    page.keyboard.press("Enter")
    page.wait_for_function(_READY, arg=None, timeout=TIMEOUT_MS)
    out: list[SystemReview] = []
    while True:
        start = time.perf_counter()
        system_id = _system_id(page.url)
        first = _first_frame(page)
        admitted = page.eval_on_selector_all(
            "[data-testid=view-calibration]", "(ns) => ns.map((n) => n.textContent.includes(' · admitted'))")
        keys: list[str] = []
        for i, ok in enumerate(admitted[:9]):
            keys += [str(i + 1), "Shift+G" if ok else "Shift+N"]
        keys.append("a")
        for key in keys:
            page.keyboard.press(key)
        page.wait_for_function(
            "([previous, last]) => document.querySelector('[data-testid=accept-guard]')?.open"
            " || document.querySelector('[data-testid=toast]')?.textContent.endsWith(last)"
            " || (!document.body.classList.contains('loading')"
            " && document.querySelector('[data-testid=view]')?.dataset.frameId !== previous)",
            arg=[first, LAST_SYSTEM_TEXT], timeout=TIMEOUT_MS)
        if page.evaluate("() => Boolean(document.querySelector('[data-testid=accept-guard]')?.open)"):
            keys.append("Enter")  # the accept guard (issue 28) lists the open label doubts: accept anyway
            page.keyboard.press("Enter")
        page.wait_for_function(
            "([previous, last]) => document.querySelector('[data-testid=toast]')?.textContent.endsWith(last)"
            " || (!document.body.classList.contains('loading')"
            " && document.querySelector('[data-testid=view]')?.dataset.frameId !== previous"
            " && document.querySelectorAll('[data-testid=view-decisions]').length"
            "    === document.querySelectorAll('[data-testid=view]').length)",
            arg=[first, LAST_SYSTEM_TEXT], timeout=TIMEOUT_MS)
        out.append(SystemReview(system_id, len(admitted), keys, time.perf_counter() - start))
        last = (page.locator("[data-testid=toast]").text_content() or "").endswith(LAST_SYSTEM_TEXT)
        if last or (limit is not None and len(out) >= limit):
            return out


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile (0..100) by linear interpolation between order statistics."""
    xs = sorted(values)
    if not xs:
        return float("nan")
    k = (len(xs) - 1) * q / 100.0
    lo = int(k)
    hi = min(lo + 1, len(xs) - 1)
    return xs[lo] + (xs[hi] - xs[lo]) * (k - lo)


def summary(reviews: list[SystemReview]) -> dict[str, Any]:
    """Systems, views, keys and seconds per system (median, p95, mean, max) and in all."""
    secs = [r.seconds for r in reviews]
    return {"systems": len(reviews), "views": sum(r.views for r in reviews),
            "keys": sum(len(r.keys) for r in reviews), "total_s": sum(secs),
            "median_s": percentile(secs, 50), "p95_s": percentile(secs, 95), "mean_s": sum(secs) / max(len(secs), 1),
            "max_s": max(secs, default=float("nan"))}


def import_dataset(dataset: Path, db: Path) -> None:
    """Import a SoccerNet-v3 tree into a new SQLite database at ``db`` (migrations, then the importer)."""
    from app.core.config import Settings
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.transfer.importing import import_soccernet_v3

    settings = Settings(database_url=f"sqlite:///{db}", data_root=dataset.parent)
    upgrade_database(settings.database_url)
    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            import_soccernet_v3(session, dataset, settings)
            session.commit()
    finally:
        engine.dispose()


def make_reviewer(db: Path, name: str = "kb-reviewer") -> str:
    """A reviewer account in ``db``; answers its password."""
    from app.db.session import make_engine, make_session_factory
    from app.services.accounts.users import create_user

    password = secrets.token_urlsafe(16)
    engine = make_engine(f"sqlite:///{db}")
    try:
        with make_session_factory(engine)() as session:
            create_user(session, name, "reviewer", password)
    finally:
        engine.dispose()
    return password


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dataset", type=Path, default=ROOT.parent / "shared" / "data" / "synthetic" / "soccernet-v3-dev",
                   help="A SoccerNet-v3 tree (default: ../shared's soccernet-v3-dev, 40 systems).")
    p.add_argument("--json", type=Path, help="Write the figures and every system's timing here.")
    p.add_argument("--headed", action="store_true", help="Show the browser.")
    args = p.parse_args(argv)
    if not args.dataset.is_dir():
        print(f"error: {args.dataset} is not a folder", file=sys.stderr)
        return 2
    from playwright.sync_api import sync_playwright

    from benchmarks.scale import Server

    with tempfile.TemporaryDirectory(prefix="v3d-kb-") as tmp:
        db = Path(tmp) / "kb.sqlite3"
        t = time.perf_counter()
        import_dataset(args.dataset.resolve(), db)
        print(f"imported {args.dataset} in {time.perf_counter() - t:.1f} s", flush=True)
        password = make_reviewer(db)
        with Server(db) as server, sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=str(CHROMIUM), headless=not args.headed,
                                         args=["--no-sandbox", "--disable-gpu"])
            try:
                page = browser.new_context(viewport={"width": 1440, "height": 900}, base_url=server.base_url).new_page()
                page.goto("/login?next=/")
                page.fill("[data-testid=login-name]", "kb-reviewer")
                page.fill("[data-testid=login-password]", password)
                page.click("[data-testid=login-submit]")
                page.wait_for_url(f"{server.base_url}/")
                reviews = review_by_keyboard(page, f"{server.base_url}/")
            finally:
                browser.close()
    s = summary(reviews)
    print(f"{s['systems']} systems, {s['views']} views, {s['keys']} keys pressed, no click")
    print(f"per system: median {s['median_s']:.2f} s, p95 {s['p95_s']:.2f} s, mean {s['mean_s']:.2f} s, "
          f"max {s['max_s']:.2f} s; whole queue {s['total_s']:.1f} s")
    if args.json:
        args.json.write_text(json.dumps({"summary": s, "systems": [asdict(r) for r in reviews]}, indent=2))
        print(f"figures written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
