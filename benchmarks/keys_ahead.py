"""Keys typed ahead on the served demo, beside CPU-bound processes: does every key a reviewer types with no pause do
what it does typed slowly?

Serves the demo as ``v3d serve --demo`` loads it (``benchmarks.scale.Server`` over a fresh SQLite file), starts
``--load`` Python processes spinning on the CPU, and, ``--tries`` times, in Debian's Chromium through Playwright:
opens the queue, presses Enter on its first row (a review pass begins there), waits until the page says it is idle
(``<body data-busy>`` absent, static/js/busy.js), types ``j j j`` with no pause, waits until idle, reads which system of
the pass is shown, then types ``k k k`` with no pause and reads it again. A try passes when ``j j j`` ends on the pass's
fourth system and ``k k k`` back on its first. Prints each try and the count that passed; exits 1 when one failed.

Usage (from the checkout)::

    .venv/bin/python benchmarks/keys_ahead.py [--tries 3] [--load 2] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import re
import secrets
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

CHROMIUM = Path("/usr/bin/chromium")
TIMEOUT_MS = 60_000
_IDLE = "() => document.body !== null && !document.body.hasAttribute('data-busy')"
_PLACE = re.compile(r"pass (\d+) of (\d+)")


def demo_database(folder: Path) -> tuple[Path, str]:
    """The demo as ``v3d serve --demo`` loads it into a new SQLite file in ``folder``, with a reviewer; answers the
    file and the reviewer's password."""
    from app.cli.serve import load_demo_if_empty
    from app.core.config import Settings
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.accounts.users import create_user

    db = folder / "demo.sqlite3"
    settings = Settings(_env_file=None, database_url=f"sqlite:///{db}")
    upgrade_database(settings.database_url)
    print(load_demo_if_empty(settings), flush=True)
    password = secrets.token_urlsafe(16)
    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            create_user(session, "keys-reviewer", "reviewer", password)
    finally:
        engine.dispose()
    return db, password


def place(page) -> int:
    """The shown system's place in the pass (1-based), as the top bar says it once the page is idle."""
    page.wait_for_function(_IDLE, timeout=TIMEOUT_MS)
    text = page.locator("[data-testid=pass-progress]").inner_text()
    m = _PLACE.search(text)
    if not m:
        raise AssertionError(f"the top bar names no place in a pass: {text!r}")
    return int(m.group(1))


def one_try(page, base_url: str) -> dict[str, Any]:
    """Queue, Enter, ``j j j`` then ``k k k`` typed with no pause (module docstring); answers where each ended."""
    page.goto(f"{base_url}/")
    page.locator("[data-testid=queue-row]").first.wait_for(timeout=TIMEOUT_MS)
    page.wait_for_function(_IDLE, timeout=TIMEOUT_MS)
    page.keyboard.press("Enter")
    page.wait_for_url(re.compile(r"/systems/\d+"), timeout=TIMEOUT_MS)
    page.locator("[data-testid=view]").first.wait_for(timeout=TIMEOUT_MS)
    start = place(page)
    t0 = time.perf_counter()
    for key in "jjj":
        page.keyboard.press(key)
    after_j = place(page)
    j_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for key in "kkk":
        page.keyboard.press(key)
    after_k = place(page)
    return {"start": start, "after_jjj": after_j, "after_kkk": after_k, "jjj_s": round(j_s, 2),
            "kkk_s": round(time.perf_counter() - t0, 2), "passed": (start, after_j, after_k) == (1, 4, 1)}


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tries", type=int, default=3)
    p.add_argument("--load", type=int, default=2, help="CPU-bound processes beside the server and the browser")
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    from playwright.sync_api import sync_playwright

    from benchmarks.scale import Server

    tries: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="v3d-keys-") as tmp:
        db, password = demo_database(Path(tmp))
        spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.load)]
        try:
            with Server(db) as server, sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=str(CHROMIUM), headless=True,
                                             args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"])
                try:
                    for n in range(args.tries):
                        # a new session each try: a pass begun afresh from the queue's first row
                        context = browser.new_context(viewport={"width": 1366, "height": 768},
                                                      base_url=server.base_url)
                        page = context.new_page()
                        page.goto("/login?next=/")
                        page.fill("[data-testid=login-name]", "keys-reviewer")
                        page.fill("[data-testid=login-password]", password)
                        page.click("[data-testid=login-submit]")
                        page.wait_for_url(f"{server.base_url}/")
                        result = one_try(page, server.base_url)
                        tries.append(result)
                        print(f"try {n + 1}: pass place {result['start']} -> j j j -> {result['after_jjj']} "
                              f"({result['jjj_s']} s) -> k k k -> {result['after_kkk']} ({result['kkk_s']} s): "
                              f"{'passed' if result['passed'] else 'FAILED'}", flush=True)
                        context.close()
                finally:
                    browser.close()
        finally:
            for spinner in spinners:
                spinner.kill()
                spinner.wait()
    passed = sum(t["passed"] for t in tries)
    print(f"{passed} of {len(tries)} tries passed beside {args.load} CPU-bound process(es)")
    if args.json:
        args.json.write_text(json.dumps({"load": args.load, "tries": tries}, indent=2))
    return 0 if passed == len(tries) else 1


if __name__ == "__main__":
    sys.exit(main())
