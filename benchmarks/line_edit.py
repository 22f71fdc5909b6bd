"""The field-line edit round trip (issue 16): the server's answer to ``PUT /api/frames/{id}/field-lines`` on the
views of 4-view systems (recalibration of the view, with the game's rig when its lines alone do not admit it,
and the recompute of its system: triangulation, reprojections, doubts, the system view answered), and the
browser's redraw of the system page once the answer is in (measured in Chromium through Playwright).

The synthetic SoccerNet-v3 dev set (``../shared/data/synthetic/soccernet-v3-dev``, or ``--dataset``) is imported
into a fresh SQLite database, served by the real server (uvicorn, one worker, a subprocess:
``benchmarks.load.served``). Server: for every view with field lines of every 4-view system, ``--rounds`` times,
one point of a class (drawn with ``--seed``) moved by up to 20 px, then the undo of that edit (the earlier
lines, ``undo_of`` its entry); each PUT timed from request to parsed answer (HTTP included). Browser: the
system page of each 4-view system, the line editor's own event ("lines-change", what a drag's release sends)
dispatched ``--browser-edits`` times on its views; per edit the page's ``v3d:redraw`` measure (the render of
the answered system view up to the next painted frame, ``static/js/systemwrites.js`` afterWrite), its script alone
(``v3d:render``), and the whole edit from the event to that frame. Prints p50 / p95 (ms) and the ratios. Usage::

    .venv/bin/python benchmarks/line_edit.py [--rounds 3] [--browser-edits 24] [--seed 0]
"""
from __future__ import annotations

import argparse
import copy
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.load import served

DEV_SET = ROOT.parent / "shared" / "data" / "synthetic" / "soccernet-v3-dev"
NAME, PASSWORD = "bench-lines", "bench-lines-password"
CHROMIUM = Path("/usr/bin/chromium")


def pct(values: list[float], q: float) -> float:
    """The ``q`` quantile (0..1) of ``values``, nearest rank (nan when empty)."""
    if not values:
        return float("nan")
    s = sorted(values)
    return s[min(len(s) - 1, max(0, int(round(q * len(s) + 0.5)) - 1))]


def summary(values: list[float]) -> dict[str, float]:
    return {"n": len(values), "p50": statistics.median(values) if values else float("nan"), "p95": pct(values, 0.95)}


def moved(lines: dict[str, Any], rng: random.Random, width: int, height: int) -> dict[str, Any]:
    """``lines`` with one point of one class (drawn by ``rng``) moved by up to 20 px, kept inside the image."""
    out = copy.deepcopy(lines)
    cls = rng.choice(sorted(out))
    poly = rng.randrange(len(out[cls]))
    i = rng.randrange(len(out[cls][poly]))
    x, y = out[cls][poly][i]
    out[cls][poly][i] = [round(min(width - 1, max(0.0, x + rng.uniform(-20, 20))), 1),
                         round(min(height - 1, max(0.0, y + rng.uniform(-20, 20))), 1)]
    return out


def prepare(workdir: Path, dataset: Path) -> tuple[str, str]:
    """A database holding ``dataset`` and an admin; answers (database URL, the admin's API token)."""
    from app.core.config import Settings
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.accounts.users import create_user
    from app.services.transfer.importing import import_soccernet_v3

    url = f"sqlite:///{workdir / 'lines.sqlite3'}"
    upgrade_database(url)
    settings = Settings(database_url=url, calibration_workers=1)
    engine = make_engine(url)
    with make_session_factory(engine)() as session:
        import_soccernet_v3(session, dataset, settings)
        session.commit()
        _, token = create_user(session, NAME, "admin", PASSWORD)
    engine.dispose()
    return url, token


def four_view_systems(client) -> list[dict[str, Any]]:
    items = client.get("/api/systems", params={"sort": "name", "limit": 500}).json()["items"]
    return [client.get(f"/api/systems/{s['id']}").json() for s in items if s["views_total"] == 4]


def server_round_trips(base: str, token: str, rounds: int, seed: int) -> dict[str, Any]:
    """Time each PUT of an edit and of its undo on every view with lines of every 4-view system."""
    import httpx

    rng = random.Random(seed)
    edit_ms: list[float] = []
    undo_ms: list[float] = []
    exact = 0
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {token}"}, timeout=120.0) as client:
        systems = four_view_systems(client)
        for _ in range(rounds):
            for system in systems:
                for view in system["views"]:
                    if not view["field_lines"]:
                        continue
                    fid = view["frame_id"]
                    current = client.get(f"/api/frames/{fid}")
                    lines, etag = current.json()["field_lines"], current.headers["etag"]
                    t0 = time.perf_counter()
                    answer = client.put(f"/api/frames/{fid}/field-lines", headers={"If-Match": etag},
                                        json={"lines": moved(lines, rng, view["width"], view["height"])})
                    answer.json()
                    edit_ms.append((time.perf_counter() - t0) * 1e3)
                    answer.raise_for_status()
                    t0 = time.perf_counter()
                    back = client.put(f"/api/frames/{fid}/field-lines", headers={"If-Match": answer.headers["etag"]},
                                      json={"lines": lines, "undo_of": int(answer.headers["x-v3d-audit-entry"])})
                    body = back.json()
                    undo_ms.append((time.perf_counter() - t0) * 1e3)
                    back.raise_for_status()
                    exact += next(v for v in body["views"] if v["frame_id"] == fid)["field_lines"] == lines
    return {"systems": len(systems), "edit": summary(edit_ms), "undo": summary(undo_ms),
            "all": summary(edit_ms + undo_ms), "undo_exact": exact, "undos": len(undo_ms)}


def wait_for_redraw(page, n: int, timeout_s: float = 60.0) -> None:
    """Wait until the page holds more than ``n`` ``v3d:redraw`` measures (polled from here: the page's
    Content-Security-Policy refuses the evaluated predicates of ``wait_for_function``)."""
    deadline = time.monotonic() + timeout_s
    while page.evaluate("performance.getEntriesByName('v3d:redraw').length") <= n:
        if time.monotonic() > deadline:
            raise TimeoutError(f"no redraw after {timeout_s:.0f} s")
        time.sleep(0.005)


def browser_redraws(base: str, edits: int, seed: int) -> Optional[dict[str, Any]]:
    """The page's redraw after each answer, and the whole edit, over ``edits`` edits spread over the
    4-view systems' pages (None without Chromium or Playwright)."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return None
    if not CHROMIUM.exists():
        return None
    rng = random.Random(seed)
    redraw: list[float] = []
    whole: list[float] = []
    script: list[float] = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), headless=True,
                                     args=["--no-sandbox", "--disable-gpu", "--no-first-run"])
        try:
            context = browser.new_context(base_url=base, viewport={"width": 1440, "height": 900})
            login = context.request.post("/api/auth/login", data={"name": NAME, "password": PASSWORD})
            assert login.ok, login.text()
            page = context.new_page()
            systems = [s for s in four_view_systems(context.request) if any(v["field_lines"] for v in s["views"])]
            per_system = max(1, edits // max(1, len(systems)))
            for system in systems:
                if len(whole) >= edits:
                    break
                page.goto(f"/systems/{system['id']}")
                page.locator("[data-testid=view] [data-testid=line-point]").first.wait_for()
                page.wait_for_load_state("networkidle")
                for _ in range(per_system):
                    k = rng.choice([i for i, v in enumerate(system["views"]) if v["field_lines"]])
                    view = page.evaluate(f"document.querySelectorAll('v3d-view')[{k}].view")
                    lines = moved(view["field_lines"], rng, view["width"], view["height"])
                    n = page.evaluate("performance.getEntriesByName('v3d:redraw').length")
                    with page.expect_response(lambda r: r.request.method == "PUT"):
                        page.evaluate("""([k, lines]) => {
                            const panel = document.querySelectorAll('v3d-view')[k];
                            window.__editStart = performance.now();
                            panel.dispatchEvent(new CustomEvent('lines-change', { bubbles: true, detail: {
                              frameId: panel.view.frame_id, lines, before: structuredClone(panel.view.field_lines),
                              what: 'benchmark edit' } }));
                        }""", [k, lines])
                    wait_for_redraw(page, n)
                    m = page.evaluate("""() => { const last = (name) => performance.getEntriesByName(name).at(-1);
                        const e = last('v3d:redraw');
                        return [e.duration, e.startTime + e.duration - window.__editStart,
                                last('v3d:render').duration]; }""")
                    redraw.append(m[0])
                    whole.append(m[1])
                    script.append(m[2])
        finally:
            browser.close()
    return {"redraw": summary(redraw), "whole": summary(whole), "script": summary(script)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", type=Path, default=DEV_SET)
    parser.add_argument("--rounds", type=int, default=3, help="edits (each with its undo) per view with lines")
    parser.add_argument("--browser-edits", type=int, default=24)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if not args.dataset.is_dir():
        print(f"dataset not found: {args.dataset}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="v3d-lines-") as tmp:
        t0 = time.perf_counter()
        url, token = prepare(Path(tmp), args.dataset)
        print(f"imported {args.dataset.name} in {time.perf_counter() - t0:.1f} s")
        with served(url, workers=1, launcher="uvicorn") as base:
            server = server_round_trips(base, token, args.rounds, args.seed)
            browser = browser_redraws(base, args.browser_edits, args.seed)
    print(f"server round trip (PUT field-lines, 4-view systems: {server['systems']}), ms:")
    for name in ("edit", "undo", "all"):
        s = server[name]
        print(f"  {name:5s} n={s['n']:3d}  p50 {s['p50']:7.1f}  p95 {s['p95']:7.1f}")
    print(f"  undos giving back the lines exactly: {server['undo_exact']} of {server['undos']}")
    if browser is None:
        print("browser: skipped (no Chromium or Playwright)")
        return 0
    r, w, j = browser["redraw"], browser["whole"], browser["script"]
    print(f"browser (Chromium), ms: redraw after the answer n={r['n']} p50 {r['p50']:.1f} p95 {r['p95']:.1f} "
          f"(its script, render(): p50 {j['p50']:.1f} p95 {j['p95']:.1f}); "
          f"whole edit (event -> painted) p50 {w['p50']:.1f} p95 {w['p95']:.1f}")
    print(f"ratios: redraw / server p50 {r['p50'] / server['all']['p50']:.3f}; "
          f"redraw share of the whole edit p50 {r['p50'] / w['p50']:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
