"""Load benchmark: concurrent annotators editing ball boxes against a real server (issue 7 item 4).

One run:

1. makes a **fresh database** and loads the built-in demo into it, as ``v3d serve --demo`` does: a
   SQLite file in a temporary folder, or, with ``--database-url postgresql+psycopg://...``, a new
   database ``v3d_load_<hex>`` on that server (dropped at the end unless ``--keep``);
2. starts the real server on a free loopback port (``v3d serve --workers N``, a subprocess; with
   ``--launcher uvicorn``: ``uvicorn --factory app.main:create_app --workers N``, the app the
   environment configures, for code that has no ``--workers`` yet);
3. runs ``--clients`` annotators at once (one thread and one ``httpx.Client`` each, started together)
   sending ``--edits`` ``PATCH /api/frames/{id}/ball`` box edits in all (dealt evenly: 20 annotators x
   500 edits = 25 each, one after the other, as issue 7's report counts 50 edits of 20 clients); every box
   is the view's original box moved by a sub-pixel amount unique to the edit, so that every edit can be
   recognised. The demo's labelled views are dealt round-robin in system order: sibling views of one
   system belong to different annotators, so one system's views are edited at once (recomputations
   race), and each view has a single owner (its last accepted edit is its expected final box);
4. checks: every accepted edit's answer (the recomputed system view) shows its box; the final state
   (``GET /api/systems/{id}``) shows each view's last accepted box (else the edit is **lost**); and,
   reading the database directly, every edited system's stored derived rows (3D ball, pairs,
   reprojections, optimised boxes, doubts) equal a fresh recomputation from its stored labels (else a
   **lost recomputation**: one edit's recomputation overwrote another's with stale labels);
5. prints p50/p95 latency of the edits, counts of 2xx/4xx/5xx and transport errors, and the checks;
   exits 1 when any edit was answered 5xx or failed, or anything was lost.

Bounded: fixed clients x edits, a timeout per request (``--timeout``) and for the whole run
(``--max-seconds``: clients stop sending after it), loopback only; the server is stopped (its own pid)
at the end.

Plug-ins for the team features of issue 7 (off by default, so the run works before they exist):
``--token T`` sends ``Authorization: Bearer T``; ``--users`` creates one annotator per client with
``v3d users add load<i> --role annotator --password-stdin`` (the token is the last stdout line);
``--if-match`` sends each write with ``If-Match`` (the ``ETag`` of ``GET /api/frames/{id}``, then of the
previous write's answer) and counts 412 answers (re-reading the ETag and retrying the same edit);
``--contend`` lets every annotator edit every view (stale writes happen; use with ``--if-match``);
``--audit`` checks that ``GET /api/audit?frame_id=`` holds one entry per accepted edit.

The module is longer than 400 lines on purpose: it is one runnable procedure (database, server,
annotators, checks, report) read top to bottom, like ``benchmarks/scale.py``, whose helpers it reuses.

Usage (from the checkout)::

    .venv/bin/python benchmarks/load.py --clients 20 --edits 500 --workers 2
    .venv/bin/python benchmarks/load.py --clients 20 --edits 500 --workers 2 \\
        --database-url postgresql+psycopg://postgres@127.0.0.1:5432/test
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections import Counter, defaultdict
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, NamedTuple, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.scale import BenchError, free_port, percentile, v3d_command

#: The demo server's PostgreSQL in the README and the CI (trust authentication).
PG_DEFAULT = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
_DERIVED_VIEW_KEYS = ("reprojected_ball", "reprojection_error_px", "optimised_box", "error_above_tau")


@dataclass
class Edit:
    """One accepted or refused edit: who, which view, the box sent (pixels), the answer and its time."""
    client: int
    frame_id: int
    box: list[float]
    status: int  # HTTP status, 0 for a transport error
    ms: float
    seq: int  # the client's edit number
    shown: Optional[list[float]] = None  # the view's box in the answer
    error: str = ""


@dataclass
class LoadReport:
    """Everything one run measured and checked."""
    clients: int
    edits_total: int
    workers: int
    backend: str
    wall_s: float = 0.0
    edits: list[Edit] = field(default_factory=list)
    stale_412: int = 0
    lost_edits: list[str] = field(default_factory=list)
    lost_recomputations: list[str] = field(default_factory=list)
    audit_mismatches: list[str] = field(default_factory=list)
    stopped_by_deadline: bool = False

    @property
    def counts(self) -> dict[str, int]:
        """Answers by class: ``2xx``, ``4xx``, ``5xx`` and ``error`` (no answer: reset, timeout)."""
        c = Counter("error" if e.status == 0 else f"{e.status // 100}xx" for e in self.edits)
        return {k: c.get(k, 0) for k in ("2xx", "4xx", "5xx", "error")}

    def latency_ms(self, q: float) -> float:
        """The ``q``-th percentile of the edits' round trips (every answered edit), ms."""
        return percentile([e.ms for e in self.edits if e.status], q)

    @property
    def ok(self) -> bool:
        """No 5xx, no transport error, nothing lost, the audit (when checked) agreeing."""
        c = self.counts
        return not (c["5xx"] or c["error"] or self.lost_edits or self.lost_recomputations or self.audit_mismatches)

    def summary(self) -> dict[str, Any]:
        """The figures as one JSON-able dict."""
        return {"backend": self.backend, "clients": self.clients, "edits_total": self.edits_total,
                "workers": self.workers, "edits_sent": len(self.edits), "wall_s": round(self.wall_s, 1),
                "edits_per_s": round(len(self.edits) / self.wall_s, 1) if self.wall_s else None,
                "p50_ms": round(self.latency_ms(50), 1), "p95_ms": round(self.latency_ms(95), 1),
                **self.counts, "stale_412": self.stale_412, "lost_edits": len(self.lost_edits),
                "lost_recomputations": len(self.lost_recomputations),
                "audit_mismatches": len(self.audit_mismatches), "stopped_by_deadline": self.stopped_by_deadline,
                "ok": self.ok}


# ----- database and server -----------------------------------------------------------------------

class DemoBallEdit(NamedTuple):
    """What :func:`demo_ball_edit` yields: the settings and a session factory of a fresh demo database, and the ball
    edit the edit benchmarks repeat (a labelled view of a 4-view system: its frame id, system id and box, px)."""

    settings: Any
    factory: Any
    frame_id: int
    system_id: int
    box: list[float]


@contextmanager
def demo_ball_edit() -> Iterator[DemoBallEdit]:
    """A fresh SQLite demo database (:func:`fresh_database`) and the first labelled view of a 4-view system in it: the
    one set-up of the benchmarks that time a ball edit in process (``edit_parts.py``, ``edit_against.py``,
    ``edit_mechanisms.py``), so that their figures are of the same edit."""
    from sqlalchemy import select

    from app.core.config import Settings
    from app.db.models import Frame
    from app.db.session import make_engine, make_session_factory

    with fresh_database(None) as url:
        engine = make_engine(url)
        factory = make_session_factory(engine)
        with factory() as s:
            frame = next(f for f in s.scalars(select(Frame).order_by(Frame.id))
                         if f.ball_label is not None and f.ball_label.box is not None and len(f.system.frames) == 4)
            fid, sid, box = frame.id, frame.system_id, list(frame.ball_label.box)
        try:
            yield DemoBallEdit(Settings(database_url=url), factory, fid, sid, box)
        finally:
            engine.dispose()


@contextmanager
def fresh_database(database_url: Optional[str], keep: bool = False, template: Optional[Path] = None) -> Iterator[str]:
    """A fresh migrated database holding the demo (as ``v3d serve --demo`` loads it); yields its URL.

    ``None``: a SQLite file in a temporary folder (a copy of the SQLite file ``template`` when given,
    one this function made before: the demo is then not imported again). A PostgreSQL URL names the
    server (its database is only used to connect): a new database ``v3d_load_<hex>`` is created there
    and dropped afterwards unless ``keep``. A SQLite URL must name a file that does not exist yet.

    Raises:
        BenchError: the SQLite file exists, or the PostgreSQL server cannot be reached.
    """
    import sqlalchemy as sa
    from sqlalchemy.engine import make_url

    from app.cli.serve import load_demo_if_empty
    from app.core.config import Settings
    from app.db.session import upgrade_database

    def prepare(url: str) -> None:
        upgrade_database(url)
        print(load_demo_if_empty(Settings(database_url=url, calibration_workers=1)), flush=True)

    if database_url is None or make_url(database_url).get_backend_name() == "sqlite":
        with tempfile.TemporaryDirectory(prefix="v3d-load-") as tmp:
            path = Path(make_url(database_url).database) if database_url else Path(tmp) / "v3d.sqlite3"
            if path.exists():
                raise BenchError(f"--database-url {database_url}: the file exists; name a new one")
            url = f"sqlite:///{path.resolve()}"
            if template is not None and database_url is None:
                shutil.copyfile(template, path)
            else:
                prepare(url)
            yield url
        return
    server = make_url(database_url)
    name = f"v3d_load_{uuid.uuid4().hex[:10]}"
    admin = sa.create_engine(server, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    except sa.exc.OperationalError as exc:
        admin.dispose()
        raise BenchError(f"PostgreSQL not reachable at {server}: {exc.orig}") from None
    url = server.set(database=name).render_as_string(hide_password=False)
    try:
        prepare(url)
        yield url
    finally:
        if not keep:
            with admin.connect() as conn:
                conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


@contextmanager
def served(database_url: str, workers: int, launcher: str = "v3d", log: Optional[Path] = None,
           start_timeout_s: float = 120.0) -> Iterator[str]:
    """The real server over ``database_url`` on a free loopback port, as a subprocess; yields its base
    URL once ``GET /`` answers and stops it (its own process group) at the end.

    Raises:
        BenchError: the server exited or did not answer within ``start_timeout_s``.
    """
    import httpx

    port = free_port()
    env = {**os.environ, "V3D_DATABASE_URL": database_url, "V3D_CALIBRATION_WORKERS": "1"}
    if launcher == "uvicorn":
        cmd = [sys.executable, "-m", "uvicorn", "--factory", "app.main:create_app", "--host", "127.0.0.1",
               "--port", str(port), "--workers", str(workers), "--log-level", "warning"]
    else:
        cmd = [*v3d_command(), "serve", "--host", "127.0.0.1", "--port", str(port), "--workers", str(workers)]
    out = open(log, "w") if log else subprocess.DEVNULL
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + start_timeout_s
        while True:
            if proc.poll() is not None:
                raise BenchError(f"the server exited ({proc.returncode}): {' '.join(cmd)}")
            try:
                if httpx.get(f"{base}/", timeout=2.0).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise BenchError(f"the server did not answer within {start_timeout_s:.0f} s")
            time.sleep(0.2)
        yield base
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, 15)  # uvicorn's supervisor and its workers: our own process group
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, 9)
                proc.wait()
        if log:
            out.close()  # type: ignore[union-attr]  # out is the open log when log is set


def user_tokens(database_url: str, clients: int) -> list[str]:
    """One annotator per client (``load<i>``, as ``v3d users add load<i> --role annotator`` stores it, through the
    same service function, in this process: a command per user cost a Python start, about 3 s, each); their first
    API tokens.

    Raises:
        BenchError: a user could not be added (the name taken, the database unreachable).
    """
    from app.core.errors import InvalidInputError
    from app.db.session import make_engine, make_session_factory
    from app.services.accounts.users import create_user

    engine = make_engine(database_url)
    try:
        with make_session_factory(engine)() as session:
            tokens = []
            for i in range(clients):
                try:
                    tokens.append(create_user(session, f"load{i}", "annotator", f"load-password-{i}")[1])
                except InvalidInputError as exc:
                    raise BenchError(f"adding the user load{i} failed: {exc}") from exc
            return tokens
    finally:
        engine.dispose()


# ----- the load ----------------------------------------------------------------------------------

def labelled_views(client: Any) -> list[tuple[int, int, list[float], int, int]]:
    """``(system_id, frame_id, box, width, height)`` of every view with a ball box, in system order."""
    systems = client.get("/api/systems", params={"sort": "name", "limit": 500}).json()["items"]
    out = []
    for s in systems:
        view = client.get(f"/api/systems/{s['id']}").json()
        for v in view["views"]:
            if v["ball"]["kind"] == "box":
                out.append((s["id"], v["frame_id"], v["ball"]["box"], v["width"], v["height"]))
    if not out:
        raise BenchError("the database holds no view with a ball box to edit")
    return out


def edit_box(box: list[float], client: int, seq: int, move_px: float = 0.0) -> list[float]:
    """The box of edit ``seq`` of ``client``: ``box`` moved by a sub-pixel amount unique to the pair
    (dx in [-1, 1] px by the client, dy in (0, 1.28] px by the edit number); with ``move_px`` > 0, dx is at least
    ``move_px`` (px) instead, to the right on even edits and to the left on odd ones (``move_px`` plus 0.1 px per
    client), so that consecutive edits of a view move its box by at least twice that (issue 29: no edit is small
    enough to leave its system's derived rows as they were)."""
    dx = round((client % 21 - 10) * 0.1, 3) if move_px <= 0 else \
        round((1 if seq % 2 == 0 else -1) * (move_px + (client % 21) * 0.1), 3)
    dy = round(((seq % 256) + 1) * 0.005, 3)
    return [round(box[0] + dx, 3), round(box[1] + dy, 3), round(box[2] + dx, 3), round(box[3] + dy, 3)]


def _shown_box(view_json: dict[str, Any], frame_id: int) -> Optional[list[float]]:
    for v in view_json.get("views", []):
        if v["frame_id"] == frame_id:
            return v["ball"]["box"]
    return None


def same_box(a: Optional[list[float]], b: Optional[list[float]]) -> bool:
    """Boxes equal to 1e-6 px (both missing counts as equal)."""
    if a is None or b is None:
        return a is b
    return all(abs(x - y) <= 1e-6 for x, y in zip(a, b, strict=False))


def run_clients(base: str, views: list[tuple[int, int, list[float], int, int]], report: LoadReport,
                tokens: list[Optional[str]], if_match: bool, contend: bool, timeout_s: float,
                max_seconds: float, move_px: float = 0.0) -> None:
    """Run the annotators (threads, started together) and append every edit to ``report.edits``."""
    import httpx

    owned: dict[int, list[int]] = defaultdict(list)  # client -> indices into views
    for i in range(len(views)):
        owned[i % report.clients].append(i)
    lock = threading.Lock()
    start = threading.Barrier(report.clients)
    stop_at = [0.0]

    def annotator(c: int) -> None:
        rng = random.Random(c)
        headers = {"Authorization": f"Bearer {tokens[c]}"} if tokens[c] else {}
        mine = list(range(len(views))) if contend else owned.get(c) or [c % len(views)]
        etags: dict[int, str] = {}
        with httpx.Client(base_url=base, timeout=timeout_s, headers=headers) as http:
            start.wait()
            for seq in range(report.edits_total // report.clients + (c < report.edits_total % report.clients)):
                if time.monotonic() > stop_at[0]:
                    report.stopped_by_deadline = True
                    return
                _, frame_id, box, _, _ = views[rng.choice(mine) if contend else mine[seq % len(mine)]]
                new = edit_box(box, c, seq, move_px)
                for _attempt in range(5 if if_match else 1):
                    h = {}
                    if if_match:
                        if frame_id not in etags:
                            etags[frame_id] = http.get(f"/api/frames/{frame_id}").headers.get("ETag", "")
                        h["If-Match"] = etags[frame_id]
                    t0 = time.perf_counter()
                    try:
                        r = http.patch(f"/api/frames/{frame_id}/ball", json={"box": new}, headers=h)
                        ms = (time.perf_counter() - t0) * 1000
                        e = Edit(c, frame_id, new, r.status_code, ms, seq)
                        if r.status_code // 100 == 2:
                            e.shown = _shown_box(r.json(), frame_id)
                            if r.headers.get("ETag"):
                                etags[frame_id] = r.headers["ETag"]
                        else:
                            e.error = r.text[:200]
                    except httpx.HTTPError as exc:
                        e = Edit(c, frame_id, new, 0, (time.perf_counter() - t0) * 1000, seq, error=repr(exc))
                    with lock:
                        report.edits.append(e)
                        if e.status == 412:
                            report.stale_412 += 1
                    if e.status != 412:
                        break
                    etags.pop(frame_id, None)  # stale: read the current ETag and re-apply

    threads = [threading.Thread(target=annotator, args=(c,), daemon=True) for c in range(report.clients)]
    t0 = time.monotonic()
    stop_at[0] = t0 + max_seconds
    for t in threads:
        t.start()
    for t in threads:
        t.join(max_seconds + timeout_s + 30)
    report.wall_s = time.monotonic() - t0


def check_final_state(client: Any, views: list[tuple[int, int, list[float], int, int]], report: LoadReport,
                      audit: bool) -> None:
    """Fill ``report.lost_edits`` (and ``audit_mismatches``): each accepted edit shows its box in its
    answer, and each view's final box is the last accepted edit of its owner (of one of its editors
    under ``--contend``)."""
    accepted: dict[int, list[Edit]] = defaultdict(list)
    for e in report.edits:
        if e.status // 100 == 2:
            accepted[e.frame_id].append(e)
            if not same_box(e.shown, e.box):
                report.lost_edits.append(f"frame {e.frame_id}: edit {e.seq} of client {e.client} answered {e.shown}")
    finals = {}
    for system_id in sorted({s for s, *_ in views}):
        for v in client.get(f"/api/systems/{system_id}").json()["views"]:
            finals[v["frame_id"]] = v["ball"]["box"]
    for frame_id, edits in accepted.items():
        last_by_client = {}
        for e in sorted(edits, key=lambda e: e.seq):
            last_by_client[e.client] = e.box
        if not any(same_box(finals.get(frame_id), b) for b in last_by_client.values()):
            report.lost_edits.append(f"frame {frame_id}: final box {finals.get(frame_id)} is no client's last "
                                     f"accepted edit {list(last_by_client.values())}")
        if audit:
            page = client.get("/api/audit", params={"frame_id": frame_id, "limit": 1})
            total = page.json().get("total") if page.status_code == 200 else None
            if total is None or total < len(edits):
                report.audit_mismatches.append(f"frame {frame_id}: {len(edits)} accepted edits, audit answered "
                                               f"{page.status_code} total={total}")


def _normalised(x: Any) -> Any:
    if isinstance(x, float):
        return round(x, 6)
    if isinstance(x, dict):
        return {k: _normalised(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_normalised(v) for v in x]
    return x


def derived_state(view: dict[str, Any]) -> dict[str, Any]:
    """The parts of a system view that a recomputation writes (3D ball, pairs, per-view reprojection
    and optimised box, doubts in a stable order), floats rounded to 1e-6."""
    return _normalised({
        "ball3d": view["ball3d"], "triangulation": view["triangulation"],
        "views": {v["frame_id"]: {k: v[k] for k in _DERIVED_VIEW_KEYS} for v in view["views"]},
        "doubts": sorted((json.dumps(d, sort_keys=True) for d in view["doubts"])),
    })


def check_recomputations(database_url: str, system_ids: list[int], report: LoadReport) -> None:
    """Fill ``report.lost_recomputations``: each system's stored derived rows against a fresh
    recomputation from its stored labels (in a transaction that is rolled back)."""
    from app.api.view_schemas import SystemView
    from app.core.config import Settings
    from app.db.models import System
    from app.db.session import make_engine, make_session_factory
    from app.services.curation.system_page import system_page
    from app.services.derivation.recompute import recompute_system

    def system_view(session, system_id):  # the system view's JSON, as GET /api/systems/{id} answers it
        return SystemView.of(system_page(session, system_id)).model_dump(mode="json", by_alias=True)

    settings = Settings(database_url=database_url, calibration_workers=1)
    engine = make_engine(database_url)
    try:
        with make_session_factory(engine)() as session:
            for system_id in system_ids:
                stored = derived_state(system_view(session, system_id))
                recompute_system(session, session.get(System, system_id), settings)
                session.flush()
                fresh = derived_state(system_view(session, system_id))
                if stored != fresh:
                    diff = sorted(k for k in fresh if fresh[k] != stored[k])
                    report.lost_recomputations.append(f"system {system_id}: stored {diff} differ from a recomputation")
                session.rollback()
    finally:
        engine.dispose()


def run_load(database_url: Optional[str] = None, clients: int = 20, edits: int = 500, workers: int = 2, *,
             launcher: str = "v3d", token: Optional[str] = None, users: bool = True, if_match: bool = True,
             contend: bool = False, audit: bool = False, timeout_s: float = 60.0, max_seconds: float = 1800.0,
             keep: bool = False, log: Optional[Path] = None, template: Optional[Path] = None,
             move_px: float = 0.0) -> LoadReport:
    """One bounded run (module docstring): fresh database with the demo, server, annotators, checks.

    Raises:
        BenchError: the database or the server could not be set up.
    """
    import httpx
    from sqlalchemy.engine import make_url

    backend = make_url(database_url).get_backend_name() if database_url else "sqlite"
    report = LoadReport(clients, edits, workers, backend)
    with fresh_database(database_url, keep=keep, template=template) as url:
        tokens: list[Optional[str]] = user_tokens(url, clients) if users else [token] * clients  # type: ignore[list-item]  # token is given when users is not
        with served(url, workers, launcher, log=log) as base:
            headers = {"Authorization": f"Bearer {tokens[0]}"} if tokens[0] else {}
            with httpx.Client(base_url=base, timeout=timeout_s, headers=headers) as http:
                views = labelled_views(http)
                run_clients(base, views, report, tokens, if_match, contend, timeout_s, max_seconds, move_px)
                check_final_state(http, views, report, audit)
        check_recomputations(url, sorted({s for s, *_ in views}), report)
    return report


def main(argv: Optional[list[str]] = None) -> int:
    """Command line (module docstring). Returns 0 when the run is clean (no 5xx, nothing lost)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--clients", type=int, default=20, help="concurrent annotators")
    p.add_argument("--edits", type=int, default=500, help="edits in all, dealt evenly among the annotators")
    p.add_argument("--workers", type=int, default=2, help="server worker processes")
    p.add_argument("--database-url", default=None,
                   help=f"SQLite file to create, or a PostgreSQL server (e.g. {PG_DEFAULT}; a fresh database is made)")
    p.add_argument("--launcher", choices=("v3d", "uvicorn"), default="v3d")
    p.add_argument("--token", default=None, help="API token sent by every annotator (Authorization: Bearer)")
    p.add_argument("--users", action=argparse.BooleanOptionalAction, default=True,
                   help="create one annotator account per client (v3d users add; the API needs a login)")
    p.add_argument("--if-match", action=argparse.BooleanOptionalAction, default=True,
                   help="send If-Match with every write (a token's write needs it); count 412 answers")
    p.add_argument("--contend", action="store_true", help="every annotator edits every view (with --if-match)")
    p.add_argument("--audit", action="store_true", help="check GET /api/audit?frame_id= against the accepted edits")
    p.add_argument("--move-px", type=float, default=0.0,
                   help="move each box by at least this many pixels (default: sub-pixel moves)")
    p.add_argument("--timeout", type=float, default=60.0, help="seconds per request")
    p.add_argument("--max-seconds", type=float, default=1800.0, help="clients stop sending after this")
    p.add_argument("--keep", action="store_true", help="keep the PostgreSQL database")
    p.add_argument("--log", type=Path, default=None, help="write the server's output here")
    p.add_argument("--json", type=Path, default=None, help="write the figures as JSON here")
    a = p.parse_args(argv)
    try:
        report = run_load(a.database_url, a.clients, a.edits, a.workers, launcher=a.launcher, token=a.token,
                          users=a.users, if_match=a.if_match, contend=a.contend, audit=a.audit,
                          timeout_s=a.timeout, max_seconds=a.max_seconds, keep=a.keep, log=a.log,
                          move_px=a.move_px)
    except BenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    figures = report.summary()
    print(json.dumps(figures, indent=1))
    for kind, items in (("5xx/error",
                         [f"{e.status} {e.error}" for e in report.edits if e.status in (0,) or e.status >= 500]),
                        ("lost edit", report.lost_edits), ("lost recomputation", report.lost_recomputations),
                        ("audit", report.audit_mismatches)):
        for line in Counter(items).most_common(5):
            print(f"{kind}: {line[1]} x {line[0]}")
    if a.json:
        a.json.write_text(json.dumps(figures, indent=1))
    return 0 if report.ok else 1


if __name__ == "__main__":
    sys.exit(main())
