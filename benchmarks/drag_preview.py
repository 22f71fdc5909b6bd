"""The camera follows the drag (issue 29, item 5): how many calibration previews a line-point drag draws per second.

In Debian's Chromium (Playwright), a person's drag of one field-line point of a 4-view system's view is replayed:
the pointer goes down on the point, moves back and forth by up to ``--amplitude`` px at ``--moves-per-s`` moves a
second for ``--seconds``, rests until the last lines' preview is drawn, and is released (the release commits the
edit, ``PUT .../field-lines``). :func:`drag_with_preview` is that walk; it reads the page's own count of preview
answers drawn (``data-drawn`` of the dragged view's preview badge) and watches the preview requests on the wire (at
most one in flight per view is the page's rule). The figure is **answers drawn per second of moving**, with the
server's time per preview (its ``elapsed_ms``) and the round trip seen by the page.

``tests/browser/test_drag_preview_ui.py`` runs the walk on the synthetic dev set and checks what it shows;
:func:`main` builds the demo (``v3d serve --demo``'s data), serves it with ``v3d serve`` (``benchmarks.scale.Server``),
logs a reviewer in through the login page and prints the figures of ``--runs`` drags (medians), e.g.::

    .venv/bin/python benchmarks/drag_preview.py [--runs 5] [--seconds 4] [--moves-per-s 60] [--in-page]
        [--json out.json]

Browser, server and their Python share this machine's two cores: a busy machine gives pessimistic figures.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

CHROMIUM = Path("/usr/bin/chromium")
#: The page's preview route (static/js/api.js previewCalibration).
PREVIEW_PATH = "/calibration-preview"


@dataclass
class DragRun:
    """One replayed drag: ``moves`` pointer moves over ``moving_s`` seconds; ``sent`` preview requests, at most
    ``max_in_flight`` at once; ``drawn`` answers drawn while moving, so ``rate_per_s`` = drawn / moving_s;
    ``server_ms`` the median of the answers' ``elapsed_ms`` and ``round_trip_ms`` the median request-to-answer time
    the page saw; ``last_jac`` the JaC (admission gamma) of the last preview drawn before the release and
    ``stored_jac`` the one the release stored; ``commit_status`` the release's HTTP status."""

    moves: int
    moving_s: float
    sent: int
    max_in_flight: int
    drawn: int
    rate_per_s: float
    server_ms: Optional[float]
    round_trip_ms: Optional[float]
    last_jac: Optional[float]
    stored_jac: Optional[float]
    commit_status: int


#: The in-page pointer (``drag_with_preview(in_page=True)``): one ``pointermove`` on the view's SVG (where the line
#: editor listens during a drag) per point, one every ``period`` ms by the page's timer; returns the seconds taken.
_PAGE_MOVES = """async (svg, [points, period]) => {
  const t0 = performance.now();
  for (const [clientX, clientY] of points) {
    svg.dispatchEvent(new PointerEvent("pointermove", { clientX, clientY, pointerId: 1, pointerType: "mouse",
      isPrimary: true, buttons: 1, bubbles: true }));
    await new Promise((done) => setTimeout(done, period));
  }
  return (performance.now() - t0) / 1000;
}"""


#: Resolves once the view's image has arrived or failed (``.view[data-image]`` no longer ``loading``: its arrival
#: redraws the view) and the SVG's screen matrix has held over three animation frames in a row (a layout still
#: moving would move the point after it was read): a condition checked per frame, not a time.
_SETTLED = """(s) => new Promise((done) => {
  const card = s.closest(".view");
  let last = "", same = 0;
  const look = () => {
    const m = s.getScreenCTM();
    const now = m ? [m.a, m.b, m.c, m.d, m.e, m.f].join(",") : "";
    same = now && now === last ? same + 1 : 0;
    last = now;
    if (same >= 3 && (!card || card.dataset.image !== "loading")) done(true); else requestAnimationFrame(look);
  };
  requestAnimationFrame(look);
})"""


def _to_screen(view):
    """The map of a view card's image px to screen px (its SVG's screen CTM, read once: a drag scrolls nothing),
    read once the view has settled (:data:`_SETTLED`), so that the press lands on the point it aims at."""
    svg = view.locator("[data-testid=view-svg]")
    svg.evaluate(_SETTLED)
    a, b, c, d, e, f = svg.evaluate(
        "(s) => { const m = s.getScreenCTM(); return [m.a, m.b, m.c, m.d, m.e, m.f]; }")
    return lambda x, y: (a * x + c * y + e, b * x + d * y + f)


def _drawn(view) -> int:
    badge = view.locator("[data-testid=drag-preview]")
    return int(badge.get_attribute("data-drawn")) if badge.count() else 0


def drag_with_preview(page, view_index: int, point: tuple[float, float], *, seconds: float = 3.0,
                      moves_per_s: float = 60.0, amplitude_px: float = 30.0,
                      screenshot: Optional[Path] = None, in_page: bool = False) -> DragRun:
    """Drag the annotated point at image px ``point`` of view ``view_index`` (in edit mode on the system page)
    back and forth along x by up to ``amplitude_px`` image px for ``seconds``, rest until the previews in flight
    are answered, release it at ``point`` + ``amplitude_px`` / 2 and wait for the release's answer. ``screenshot``:
    a PNG of the page during the rest, the pointer still down (the preview drawn).

    The moves are Playwright's ``mouse.move``, each awaited by this process (about 30 ms a move here: the driver,
    not the page, then sets the rate), or with ``in_page`` pointer events the page dispatches to the view itself on
    a timer, ``moves_per_s`` a second whatever the driver's speed (a real pointer's pace; the press and the release
    stay Playwright's). ``moving_s`` is then the page's own clock, so a page slower than the pointer shows in it.

    Raises:
        AssertionError: no preview badge was drawn, or the release got no answer.
    """
    view = page.locator("[data-testid=view]").nth(view_index)
    in_flight: set[Any] = set()
    started: dict[Any, float] = {}
    trips: list[float] = []
    server: list[float] = []
    counts = {"sent": 0, "max": 0}

    def on_request(request) -> None:
        if PREVIEW_PATH in request.url:
            in_flight.add(request)
            started[request] = time.perf_counter()
            counts["sent"] += 1
            counts["max"] = max(counts["max"], len(in_flight))

    def on_done(request) -> None:
        if request in in_flight:
            in_flight.discard(request)
            trips.append((time.perf_counter() - started.pop(request)) * 1e3)
            response = request.response()
            if response is not None and response.ok:
                server.append(float(response.json()["elapsed_ms"]))

    page.on("request", on_request)
    page.on("requestfinished", on_done)
    page.on("requestfailed", on_done)
    try:
        x, y = point
        screen = _to_screen(view)
        page.mouse.move(*screen(x, y))
        page.mouse.down()
        drawn0 = _drawn(view)
        n = max(1, int(seconds * moves_per_s))
        # a triangle wave: out and back, 40 moves a period
        wave = [amplitude_px * (2 * ph if ph < 0.5 else 2 * (1 - ph))
                for ph in ((i % 40) / 40.0 for i in range(n))]
        if in_page:
            moving_s = view.locator("[data-testid=view-svg]").evaluate(_PAGE_MOVES, [
                [screen(x + dx, y) for dx in wave], 1000.0 / moves_per_s])
        else:
            t0 = time.perf_counter()
            for dx in wave:
                page.mouse.move(*screen(x + dx, y))
                page.wait_for_timeout(1000.0 / moves_per_s)
            moving_s = time.perf_counter() - t0
        drawn = _drawn(view) - drawn0
        page.mouse.move(*screen(x + amplitude_px / 2, y))
        deadline = time.monotonic() + 10.0
        while (in_flight or not view.locator("[data-testid=drag-preview]").count()) and time.monotonic() < deadline:
            page.wait_for_timeout(20)
        page.wait_for_timeout(150)  # the last coalesced lines' preview, if one was waiting
        while in_flight and time.monotonic() < deadline:
            page.wait_for_timeout(20)
        badge = view.locator("[data-testid=drag-preview]")
        assert badge.count(), (f"no preview was drawn during the drag ({counts['sent']} previews sent, "
                               f"{drawn} drawn while moving)")
        last = badge.get_attribute("data-jac")
        if screenshot is not None:
            page.screenshot(path=str(screenshot))
        with page.expect_response(lambda r: r.request.method == "PUT" and "/field-lines" in r.url) as answer:
            page.mouse.up()
        status = answer.value.status
        stored = ((answer.value.json()["views"][view_index]["calibration"] or {}).get("jac", {})
                  if answer.value.ok else {})
    finally:
        page.remove_listener("request", on_request)
        page.remove_listener("requestfinished", on_done)
        page.remove_listener("requestfailed", on_done)
    first = next(iter(stored.values()), None) if stored else None
    return DragRun(moves=n, moving_s=round(moving_s, 3), sent=counts["sent"], max_in_flight=counts["max"],
                   drawn=drawn, rate_per_s=round(drawn / moving_s, 2),
                   server_ms=round(statistics.median(server), 2) if server else None,
                   round_trip_ms=round(statistics.median(trips), 2) if trips else None,
                   last_jac=float(last) if last not in (None, "") else None, stored_jac=first, commit_status=status)


def open_for_editing(page, system_id: int, view_index: int) -> None:
    """Open the system page, select view ``view_index`` and put its field lines in edit mode (keys 1..9, e)."""
    page.goto(f"/systems/{system_id}")
    view = page.locator("[data-testid=view]").nth(view_index)
    view.locator("[data-testid=line-point]").first.wait_for()
    page.keyboard.press(str(view_index + 1))
    page.keyboard.press("e")
    view.locator("[data-testid=lines-bar]").wait_for()
    view.scroll_into_view_if_needed()


def inner_point(view: dict[str, Any], margin: float = 100.0) -> tuple[float, float]:
    """An annotated point of the view's best-fitting class well inside its image (px): the one a drag moves."""
    residuals = view["calibration"]["residuals_px"]
    def inside(p):
        return margin < p[0] < view["width"] - margin and margin / 2 < p[1] < view["height"] - margin / 2

    lines = view["field_lines"]
    cls = min((c for c in lines if c in residuals and any(map(inside, lines[c][0]))), key=residuals.get)
    return tuple(next(p for p in lines[cls][0] if inside(p)))


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=5, help="Drags measured (each on the next view of the system).")
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--moves-per-s", type=float, default=60.0)
    p.add_argument("--in-page", action="store_true", help="Pointer moves dispatched by the page on a timer, at "
                   "--moves-per-s whatever the driver's speed (default: Playwright's mouse, one awaited call a move).")
    p.add_argument("--json", type=Path)
    p.add_argument("--screenshot", type=Path, help="A PNG of the page during the last drag's rest (pointer down).")
    args = p.parse_args(argv)
    from playwright.sync_api import sync_playwright

    from benchmarks.keyboard_review import make_reviewer
    from benchmarks.scale import Server, build_demo_db

    runs: list[DragRun] = []
    with tempfile.TemporaryDirectory(prefix="v3d-drag-") as tmp:
        db = build_demo_db(Path(tmp))
        password = make_reviewer(db)
        with Server(db) as server, sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox", "--disable-gpu"])
            try:
                page = browser.new_context(viewport={"width": 1440, "height": 900}, base_url=server.base_url).new_page()
                page.goto("/login?next=/")
                page.fill("[data-testid=login-name]", "kb-reviewer")
                page.fill("[data-testid=login-password]", password)
                page.click("[data-testid=login-submit]")
                page.wait_for_url(f"{server.base_url}/")
                systems = page.request.get("/api/systems?sort=name&limit=50").json()["items"]
                system = next(s for s in systems if s["views_total"] == 4)
                for r in range(args.runs):
                    detail = page.request.get(f"/api/systems/{system['id']}").json()
                    k = r % 4
                    view = detail["views"][k]
                    open_for_editing(page, system["id"], k)
                    shot = args.screenshot if r == args.runs - 1 else None
                    run = drag_with_preview(page, k, inner_point(view), seconds=args.seconds,
                                            moves_per_s=args.moves_per_s, screenshot=shot, in_page=args.in_page)
                    runs.append(run)
                    print(f"drag {r + 1} (view {k + 1}): {run.moves} moves and {run.drawn} previews drawn in "
                          f"{run.moving_s:.2f} s = {run.rate_per_s:.1f}/s; {run.sent} sent, at most "
                          f"{run.max_in_flight} in flight; server {run.server_ms} ms, round trip {run.round_trip_ms} "
                          f"ms; JaC last preview {run.last_jac} stored {run.stored_jac}", flush=True)
            finally:
                browser.close()
    rates = [r.rate_per_s for r in runs]
    print(f"system {system['name']!r} (4 views): previews drawn per second of dragging, median "
          f"{statistics.median(rates):.1f} (min {min(rates):.1f}, max {max(rates):.1f}); server ms median "
          f"{statistics.median([r.server_ms for r in runs if r.server_ms]):.1f}; round trip median "
          f"{statistics.median([r.round_trip_ms for r in runs if r.round_trip_ms]):.1f} ms")
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in runs], indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
