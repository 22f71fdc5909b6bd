"""Scale benchmark: a SoccerNet-v3-size database against the 9-system demo (issue 8).

One run:

1. builds the **demo** database (``app.demo.generate_demo_dataset`` imported as ``v3d serve --demo``
   does, :func:`build_demo_db`) and the **scale** database: ``v3d import soccernet-v3`` of the
   unpacked scale set run as a subprocess (:func:`run_import`), measuring its wall time, frames per
   second and the peak resident memory of the whole process tree (the CLI and its calibration
   workers, summed, sampled with psutil every 0.2 s: :class:`TreeMemorySampler`);
2. serves each database with the real server (``v3d serve`` on a free loopback port, a subprocess:
   :class:`Server`) and measures with a bounded httpx client (:func:`measure_server`; loopback
   only, a fixed number of requests, each with a timeout):

   * queue page: ``GET /api/systems`` with the default sort (p50 / p95), and a mix of
     filter / sort / offset variants (:data:`QUEUE_VARIANTS`, p95); every sort (:data:`QUEUE_SORTS`) at
     random depths, by ``offset`` and by cursor (``after=`` / ``before=`` the page's ``next_cursor`` /
     ``prev_cursor``; p95, issue 16);
   * system page: ``GET /api/systems/{id}`` on random systems (p95);
   * ball edit round trip: ``PATCH /api/frames/{id}/ball`` (with ``If-Match``, the view's ETag) moving an existing box
     by one pixel and back, the answer parsed (p95 over both PATCHes; the database ends as it started, up to the
     ``edited`` mark and the time stamps);
   * export: ``GET /api/exports/soccernet-v3d?all=true`` streamed to nowhere (time to the first
     byte and to the last);

3. prints a table of the figures with the ratio scale / demo against the targets of issue 8
   (:data:`TARGETS`), and writes them as JSON with ``--json OUT``.

Usage (from the checkout, with the ``bench`` extra installed: ``pip install -e '.[bench]'``)::

    .venv/bin/python benchmarks/scale.py --scale-dir /work/scale-data/soccernet-v3-scale \\
        [--games N] [--requests 200] [--db var/scale.sqlite3] [--skip-import | --import-only] [--with-images]
        [--json out.json]

``--scale-dir`` is the unpacked ``shared/data/synthetic/soccernet-v3-scale.tar.gz`` (unpack it
outside the checkout; never commit it). ``--games N`` imports only the first N games (sorted by
path, as the importer walks them) for a quick run. ``--db`` keeps the scale database at that path
(default: a temporary folder); with ``--skip-import`` that database is reused as it is and the
import is not measured; with ``--import-only`` only the import is measured (its wall time, frames
per second, peak memory and the CPU time of its process tree). ``--work-dir`` holds the demo database and the subset
(default: temporary).

The full set (400 games, 12,800 systems, 35,550 views) takes about 10 minutes to import on 2 cores.
Timings on a machine shared with other jobs are pessimistic: run it under ``nice`` only when you
must, and say so with the figures.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import re
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: Per measure, (largest ratio scale / demo, largest absolute value): the system page, the queue and a ball edit
#: within 1.5x of the demo's p95, so that a page costs at 12,800 systems what it costs at 9; the queue at random
#: depths within 2x; the whole export within 10 s.
TARGETS: dict[str, tuple[Optional[float], Optional[float]]] = {
    "queue_p95_ms": (1.5, 40.0),
    "queue_depth_p95_ms": (2.0, 40.0),  # every sort at random depths, by offset and by cursor
    "system_p95_ms": (1.5, 60.0),
    "ball_edit_p95_ms": (1.5, 80.0),
    "export_s": (None, 10.0),
}
#: Import targets: at least this many frames per second, at most this peak of the process tree's proportional set
#: size (MB: a page the pool's forked workers share is counted once, as the machine holds it). The RSS sum, which
#: counts a shared page once per process, is printed beside it.
IMPORT_MIN_FPS = 150.0
IMPORT_MAX_PEAK_MB = 1024.0
#: Queue requests besides the default one: filters, sorts and a deep offset (``{mid}``: half the total).
QUEUE_VARIANTS: tuple[dict[str, Any], ...] = (
    {"sort": "name"},
    {"sort": "lowest_jac"},
    {"sort": "-worst_error", "status": "pending"},
    {"sort": "-worst_error", "error_min": 5.0},
    {"sort": "-lowest_jac", "jac_max": 0.9},
    {"sort": "-worst_error", "offset": "{mid}"},
)
#: Every order of the queue, measured at random depths (issue 16 item 6).
QUEUE_SORTS = ("-doubts", "doubts", "-worst_error", "worst_error", "lowest_jac", "-lowest_jac", "name", "-name")
_SAMPLE_S = 0.2
_TIMEOUT_S = 120.0


class BenchError(RuntimeError):
    """A missing input or a step that failed; the message names it."""


# ----- processes and memory ---------------------------------------------------------------------

def v3d_command() -> list[str]:
    """The ``v3d`` command of this interpreter's environment (its console script, else ``-c``)."""
    script = Path(sys.executable).parent / "v3d"
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from app.cli import main; sys.argv[0] = 'v3d'; main()"]


def _psutil():
    try:
        import psutil
    except ImportError:
        raise BenchError("psutil is missing: pip install -e '.[bench]'") from None
    return psutil


class TreeMemorySampler:
    """Peak resident memory (MB) of a process and all its descendants, summed, sampled every
    ``interval_s`` seconds in a thread. ``peak_mb`` and ``peak_processes`` hold the largest sum seen
    and how many processes made it; ``cpu_s`` the CPU time (user + system, s) of every process of
    the tree as last sampled, summed (a figure the machine's other load barely changes; up to one
    interval of a process's last CPU time is missed), ``main_cpu_s`` that of the root process alone
    (the import's serial part: reading, storing, recomputing; the rest is its calibration workers).

    The RSS sum counts every page a process maps once per process: the pool's workers are forked from one forkserver
    and share its imported libraries' pages, and a shared library's file pages count in every process that maps them
    (more of them when other processes on the machine keep them in the page cache), so the sum over-counts what the
    tree holds and moves with the machine. ``peak_pss_mb`` is the largest sum of proportional set sizes (each shared
    page divided among the processes that map it, ``/proc/PID/smaps_rollup``): what the tree holds, shared pages
    counted once (those it shares with processes outside the tree only in part). ``main_rss_mb`` and ``main_pss_mb``
    are the root process's at each sum's peak."""

    def __init__(self, pid: int, interval_s: float = _SAMPLE_S) -> None:
        self.psutil = _psutil()
        self.pid, self.interval_s = pid, interval_s
        self.peak_mb, self.peak_processes, self.samples = 0.0, 0, 0
        self.peak_pss_mb, self.main_rss_mb, self.main_pss_mb = 0.0, 0.0, 0.0
        self._cpu: dict[tuple[int, float], float] = {}  # (pid, create time) -> CPU seconds
        self.main_cpu_s = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def sample(self) -> float:
        """One sum of RSS (MB) over the tree; processes that end meanwhile are skipped."""
        ps = self.psutil
        try:
            root = ps.Process(self.pid)
            procs = [root, *root.children(recursive=True)]
        except ps.NoSuchProcess:
            return 0.0
        total, pss, n = 0, 0, 0
        main_rss, main_pss = 0, 0
        for p in procs:
            try:
                mem = p.memory_full_info()
                total += mem.rss
                pss += mem.pss
                n += 1
                t = p.cpu_times()
                self._cpu[(p.pid, p.create_time())] = t.user + t.system
                if p.pid == self.pid:
                    self.main_cpu_s = t.user + t.system
                    main_rss, main_pss = mem.rss, mem.pss
            except (ps.NoSuchProcess, ps.AccessDenied):
                pass
        mb = total / 2**20
        self.samples += 1
        if mb > self.peak_mb:
            self.peak_mb, self.peak_processes, self.main_rss_mb = mb, n, main_rss / 2**20
        if pss / 2**20 > self.peak_pss_mb:
            self.peak_pss_mb, self.main_pss_mb = pss / 2**20, main_pss / 2**20
        return mb

    @property
    def cpu_s(self) -> float:
        """CPU seconds of the tree's processes (see the class docstring)."""
        return float(sum(self._cpu.values()))

    def _run(self) -> None:
        while not self._stop.is_set():
            self.sample()
            self._stop.wait(self.interval_s)

    def __enter__(self) -> "TreeMemorySampler":
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        self._thread.join()


def free_port() -> int:
    """A free TCP port on 127.0.0.1."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def sqlite_url(path: Path) -> str:
    """SQLAlchemy URL of a SQLite file."""
    return f"sqlite:///{Path(path).resolve()}"


# ----- databases ---------------------------------------------------------------------------------

def build_demo_db(work_dir: Path) -> Path:
    """Migrate a fresh SQLite database under ``work_dir`` and import the demo dataset into it, as
    ``v3d serve --demo`` does (:func:`app.cli.serve.load_demo_if_empty`). Returns its path."""
    from app.cli.serve import load_demo_if_empty
    from app.core.config import Settings
    from app.db.session import upgrade_database

    db = Path(work_dir) / "demo" / "v3d-demo.sqlite3"
    db.parent.mkdir(parents=True, exist_ok=True)
    settings = Settings(database_url=sqlite_url(db))
    upgrade_database(settings.database_url)
    load_demo_if_empty(settings)
    return db


def game_dirs(scale_dir: Path) -> list[Path]:
    """The game folders of a SoccerNet-v3 tree (those holding ``Labels-v3.json``), sorted by path as
    the importer walks them. Raises :class:`BenchError` naming the folder when there is none."""
    scale_dir = Path(scale_dir)
    if not scale_dir.is_dir():
        raise BenchError(f"--scale-dir {scale_dir}: no such folder (unpack "
                         "shared/data/synthetic/soccernet-v3-scale.tar.gz outside the checkout)")
    games = [p.parent for p in sorted(scale_dir.rglob("Labels-v3.json"))]
    if not games:
        raise BenchError(f"--scale-dir {scale_dir}: no <league>/<season>/<game>/Labels-v3.json below it")
    return games


def subset_tree(scale_dir: Path, games: int, dest: Path, images: bool = False) -> Path:
    """Copy the first ``games`` game folders of ``scale_dir`` (labels only, small) into ``dest``,
    keeping the ``<league>/<season>/<game>`` layout; with ``images``, each game also gets a ``Frames-v3.zip``
    (:func:`write_frame_images`), so that the import checks every image's header. Returns ``dest``."""
    chosen = game_dirs(scale_dir)[:games]
    if dest.exists():
        shutil.rmtree(dest)
    for g in chosen:
        target = dest / g.relative_to(scale_dir)
        shutil.copytree(g, target)
        if images:
            write_frame_images(target)
    return dest


def write_frame_images(game_dir: Path) -> int:
    """Write ``game_dir/Frames-v3.zip`` (stored, not deflated, as a release's) with one PNG per action and replay
    image of its ``Labels-v3.json``, grey, at the size the labels give it (the scale set ships no images; the
    import then opens each member and checks its header: issue 15, item 2). Returns the number of images."""
    import zipfile

    import cv2
    import numpy as np

    data = json.loads((game_dir / "Labels-v3.json").read_text(encoding="utf-8"))
    encoded: dict[tuple[int, int], bytes] = {}
    n = 0
    with zipfile.ZipFile(game_dir / "Frames-v3.zip", "w", zipfile.ZIP_STORED) as zf:
        for table in ("actions", "replays"):
            for name, entry in (data.get(table) or {}).items():
                meta = entry.get("imageMetadata") or {}
                size = (int(meta.get("width", 1920)), int(meta.get("height", 1080)))
                if size not in encoded:
                    encoded[size] = cv2.imencode(".png", np.full((size[1], size[0], 3), 96, np.uint8))[1].tobytes()
                zf.writestr(name, encoded[size])
                n += 1
    return n


@dataclass
class ImportFigures:
    """What :func:`run_import` measured."""

    seconds: float
    games: int
    systems: int
    frames: int
    frames_per_s: float
    peak_mb: float
    peak_processes: int
    stage_seconds: dict[str, float] = field(default_factory=dict)
    cpu_s: float = 0.0
    cpu_ms_per_frame: float = 0.0
    main_cpu_ms_per_frame: float = 0.0
    load_average: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: :class:`TreeMemorySampler`'s ``peak_pss_mb`` (shared pages counted once), and the main process's RSS at the
    #: RSS sum's peak and PSS at the PSS sum's peak (MB).
    peak_pss_mb: float = 0.0
    main_rss_mb: float = 0.0
    main_pss_mb: float = 0.0


_IMPORTED = re.compile(r"imported .*?: (\d+) game\(s\), (\d+) system\(s\), (\d+) frame\(s\)")


def run_import(tree: Path, db: Path, workers: Optional[int] = None, checkout: Optional[Path] = None) -> ImportFigures:
    """Run ``v3d import soccernet-v3 TREE --database-url sqlite:///DB`` as a subprocess (a fresh
    database: ``db`` is removed first), timing it end to end (migration included) and sampling the
    RSS of its process tree; with ``checkout``, that checkout's code (run from its folder, on its ``PYTHONPATH``)
    instead of this one's. Raises :class:`BenchError` with the CLI's last lines when it fails."""
    db = Path(db)
    db.parent.mkdir(parents=True, exist_ok=True)
    for suffix in ("", "-wal", "-shm"):
        Path(f"{db}{suffix}").unlink(missing_ok=True)
    cmd = [*v3d_command(), "import", "soccernet-v3", str(tree), "--database-url", sqlite_url(db)]
    if workers is not None:
        cmd += ["--workers", str(workers)]
    log = db.with_suffix(".import.log")
    t0 = time.perf_counter()
    with open(log, "w") as out:
        env = None if checkout is None else {**os.environ, "PYTHONPATH": str(checkout)}
        proc = subprocess.Popen(cmd, cwd=checkout or ROOT, env=env, stdout=out, stderr=subprocess.STDOUT)
        with TreeMemorySampler(proc.pid) as mem:
            rc = proc.wait()
    seconds = time.perf_counter() - t0
    text = log.read_text(errors="replace")
    if rc != 0:
        raise BenchError(f"v3d import failed (exit {rc}); last lines of {log}:\n" + "\n".join(text.splitlines()[-15:]))
    m = _IMPORTED.search(text)
    if not m:
        raise BenchError(f"v3d import printed no 'imported ...' summary; see {log}")
    games, systems, frames = (int(x) for x in m.groups())
    return ImportFigures(seconds=seconds, games=games, systems=systems, frames=frames,
                         frames_per_s=frames / seconds, peak_mb=mem.peak_mb, peak_processes=mem.peak_processes,
                         stage_seconds=_stage_seconds(text), cpu_s=mem.cpu_s, cpu_ms_per_frame=1e3 * mem.cpu_s / frames,
                         main_cpu_ms_per_frame=1e3 * mem.main_cpu_s / frames,
                         load_average=os.getloadavg(), peak_pss_mb=mem.peak_pss_mb, main_rss_mb=mem.main_rss_mb,
                         main_pss_mb=mem.main_pss_mb)


_BAR = re.compile(r"^(\w[\w ]*?): +\d+%.*?\[(\d+):(\d+)(?::(\d+))?<", re.M)


def _stage_seconds(log_text: str) -> dict[str, float]:
    """Elapsed seconds per tqdm stage bar (the last state of each bar in the log)."""
    out: dict[str, float] = {}
    for line in re.split(r"[\r\n]", log_text):
        m = _BAR.match(line.strip())
        if m:
            a, b, c = m.group(2), m.group(3), m.group(4)
            secs = int(a) * 3600 + int(b) * 60 + int(c) if c else int(a) * 60 + int(b)
            out[m.group(1)] = float(secs)
    return out


# ----- the server --------------------------------------------------------------------------------

def bench_token(db: Path, name: str = "bench-admin") -> str:
    """An API token of the admin ``name`` in the SQLite database ``db`` (made on first use): the
    benchmark's requests authenticate like a script's (``Authorization: Bearer``)."""
    from app.core.errors import InvalidInputError
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.accounts.users import create_user, issue_token

    url = sqlite_url(db)
    upgrade_database(url)
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            try:
                return create_user(session, name, "admin", secrets.token_urlsafe(16))[1]
            except InvalidInputError:
                return issue_token(session, name).token
    finally:
        engine.dispose()


class Server:
    """``v3d serve`` on a free loopback port over a SQLite database, as a subprocess; a context
    manager that waits until ``/api/health`` answers and stops the server (its own pid) on exit.
    ``headers`` carry an admin's API token (:func:`bench_token`) for the measured requests."""

    def __init__(self, db: Path, start_timeout_s: float = 90.0) -> None:
        self.db, self.port, self.start_timeout_s = Path(db), free_port(), start_timeout_s
        self.base_url = f"http://127.0.0.1:{self.port}"
        self.proc: Optional[subprocess.Popen] = None
        self.log = self.db.with_suffix(".serve.log")

    def __enter__(self) -> "Server":
        import httpx

        if not self.db.is_file():
            raise BenchError(f"database {self.db} does not exist")
        self.headers = {"Authorization": f"Bearer {bench_token(self.db)}"}
        env = {**os.environ, "V3D_DATABASE_URL": sqlite_url(self.db)}
        self._out = open(self.log, "w")
        self.proc = subprocess.Popen([*v3d_command(), "serve", "--host", "127.0.0.1", "--port", str(self.port)],
                                     cwd=ROOT, env=env, stdout=self._out, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + self.start_timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                self._close()
                raise BenchError(f"v3d serve exited ({self.proc.returncode}); see {self.log}")
            try:
                if httpx.get(f"{self.base_url}/api/health", timeout=2.0).status_code == 200:
                    return self
            except httpx.HTTPError:
                pass
            time.sleep(0.2)
        self.__exit__()
        raise BenchError(f"v3d serve did not answer within {self.start_timeout_s:.0f} s; see {self.log}")

    def __exit__(self, *exc: Any) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._close()

    def _close(self) -> None:
        if getattr(self, "_out", None):
            self._out.close()
            self._out = None


# ----- measures ----------------------------------------------------------------------------------

def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile (0-100, linear interpolation) of ``values``.

    >>> percentile([1.0, 2.0, 3.0, 4.0, 5.0], 50), percentile([1.0, 2.0, 3.0, 4.0, 5.0], 95)
    (3.0, 4.8)
    """
    if not values:
        return float("nan")
    xs = sorted(values)
    k = (len(xs) - 1) * q / 100.0
    lo = int(k)
    hi = min(lo + 1, len(xs) - 1)
    return round(xs[lo] + (xs[hi] - xs[lo]) * (k - lo), 6)


def _timed(client: Any, method: str, url: str, **kw: Any) -> tuple[float, Any]:
    """(ms, parsed JSON) of one request whose answer must be 200."""
    t0 = time.perf_counter()
    r = client.request(method, url, **kw)
    body = r.json()
    ms = (time.perf_counter() - t0) * 1000.0
    if r.status_code != 200:
        raise BenchError(f"{method} {url} answered {r.status_code}: {str(body)[:300]}")
    return ms, body


def _system_ids(client: Any, total: int, n: int, rng: random.Random) -> list[int]:
    """``n`` random system ids, each read from the queue at a random offset (not timed)."""
    ids = []
    for _ in range(n):
        r = client.get("/api/systems", params={"limit": 1, "offset": rng.randrange(total)})
        items = r.json()["items"]
        if items:
            ids.append(items[0]["id"])
    return ids


def measure_server(base_url: str, requests: int = 100, seed: int = 0, export: bool = True,
                   headers: Optional[dict[str, str]] = None) -> dict[str, Any]:
    """Measure one running server (loopback only): ``requests`` queue pages with the default sort,
    as many spread over :data:`QUEUE_VARIANTS`, ``requests`` system pages, up to ``requests`` ball
    edits (half nudges, half restores) and one full export. Milliseconds, except ``export_s``.
    ``headers`` authenticate the requests (``Server.headers``: an admin's API token)."""
    import httpx

    if not base_url.startswith(("http://127.", "http://localhost", "http://[::1]")):
        raise BenchError(f"{base_url}: this benchmark only talks to loopback servers")
    rng = random.Random(seed)
    out: dict[str, Any] = {"requests": requests}
    with httpx.Client(base_url=base_url, timeout=_TIMEOUT_S, headers=headers) as client:
        first = client.get("/api/systems").json()
        total = int(first["total"])
        if total == 0:
            raise BenchError(f"{base_url}: the database holds no system")
        out["systems"] = total
        for _ in range(3):  # warm-up: imports, caches, connection pool
            client.get("/api/systems")
        queue = [_timed(client, "GET", "/api/systems")[0] for _ in range(requests)]
        out["queue_p50_ms"], out["queue_p95_ms"] = percentile(queue, 50), percentile(queue, 95)
        variants: dict[str, list[float]] = {}
        for i in range(requests):
            v = dict(QUEUE_VARIANTS[i % len(QUEUE_VARIANTS)])
            key = "&".join(f"{k}={v[k]}" for k in sorted(v))
            if v.get("offset") == "{mid}":
                v["offset"] = total // 2
            variants.setdefault(key, []).append(_timed(client, "GET", "/api/systems", params=v)[0])
        every = [x for xs in variants.values() for x in xs]
        out["queue_variants_p95_ms"] = percentile(every, 95)
        out["queue_variant_p95_ms"] = {k: percentile(xs, 95) for k, xs in variants.items()}
        # every sort at random depths: a page by offset, then the pages after and before it by its cursors
        depth: dict[str, list[float]] = {}
        for i in range(requests):
            sort = QUEUE_SORTS[i % len(QUEUE_SORTS)]
            ms, page = _timed(client, "GET", "/api/systems", params={"sort": sort, "offset": rng.randrange(total)})
            depth.setdefault(f"{sort} offset", []).append(ms)
            for key, param in (("next_cursor", "after"), ("prev_cursor", "before")):
                if page.get(key):
                    depth.setdefault(f"{sort} cursor", []).append(
                        _timed(client, "GET", "/api/systems", params={"sort": sort, param: page[key]})[0])
        out["queue_depth_p95_ms"] = percentile([x for xs in depth.values() for x in xs], 95)
        out["queue_depth_variant_p95_ms"] = {k: percentile(xs, 95) for k, xs in depth.items()}

        ids = _system_ids(client, total, requests, rng)
        system = [_timed(client, "GET", f"/api/systems/{i}")[0] for i in ids]
        out["system_p50_ms"], out["system_p95_ms"] = percentile(system, 50), percentile(system, 95)

        edits: list[float] = []
        for sid in ids:
            if len(edits) >= requests:
                break
            _, view = _timed(client, "GET", f"/api/systems/{sid}")
            boxed = [v for v in view["views"] if v["ball"]["kind"] == "box" and v["ball"]["box"]]
            if not boxed:
                continue
            v = rng.choice(boxed)
            box = v["ball"]["box"]
            nudged = [box[0] + 1.0, box[1], box[2] + 1.0, box[3]]
            etag = v["etag"]  # a script's write names the version it was made against (If-Match)
            for b in (nudged, box):
                ms, answer = _timed(client, "PATCH", f"/api/frames/{v['frame_id']}/ball", json={"box": b},
                                    headers={"If-Match": etag})
                if answer["id"] != sid:
                    raise BenchError(f"PATCH /api/frames/{v['frame_id']}/ball answered system {answer['id']}, "
                                     f"not {sid}")
                etag = next(x["etag"] for x in answer["views"] if x["frame_id"] == v["frame_id"])
                edits.append(ms)
        out["ball_edits"] = len(edits)
        out["ball_edit_p50_ms"], out["ball_edit_p95_ms"] = percentile(edits, 50), percentile(edits, 95)

        if export:
            t0 = time.perf_counter()
            first_byte, size = None, 0
            with client.stream("GET", "/api/exports/soccernet-v3d", params={"all": "true"}, timeout=600.0) as r:
                if r.status_code != 200:
                    raise BenchError(f"GET /api/exports/soccernet-v3d?all=true answered {r.status_code}")
                for chunk in r.iter_bytes():
                    if first_byte is None:
                        first_byte = time.perf_counter() - t0
                    size += len(chunk)
            out["export_s"] = time.perf_counter() - t0
            out["export_first_byte_s"] = first_byte
            out["export_mb"] = size / 2**20
    return out


# ----- report ------------------------------------------------------------------------------------

def compare(demo: dict[str, Any], scale: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows ``{measure, demo, scale, ratio, target, ok}`` of the scale / demo comparison against
    :data:`TARGETS` (``ok`` None when a figure is missing)."""
    rows = []
    for key in ("queue_p50_ms", "queue_p95_ms", "queue_variants_p95_ms", "queue_depth_p95_ms", "system_p95_ms",
                "ball_edit_p95_ms",
                "export_s"):
        d, s = demo.get(key), scale.get(key)
        ratio = s / d if d and s is not None else None
        max_ratio, max_abs = TARGETS.get(key, (None, None))
        checks = []
        if max_ratio is not None and ratio is not None:
            checks.append(ratio <= max_ratio)
        if max_abs is not None and s is not None:
            checks.append(s <= max_abs)
        target = " and ".join(x for x in (f"<= {max_ratio:g}x" if max_ratio else "",
                                          f"<= {max_abs:g}" if max_abs else "") if x)
        rows.append({"measure": key, "demo": d, "scale": s, "ratio": ratio, "target": target or "-",
                     "ok": all(checks) if checks else None})
    return rows


def format_report(result: dict[str, Any]) -> str:
    """The printed table of a run's ``result`` (as written by ``--json``)."""
    lines = []
    imp = result.get("import")
    if imp:
        ok_fps = imp["frames_per_s"] >= IMPORT_MIN_FPS
        peak_pss = imp.get("peak_pss_mb") or imp["peak_mb"]
        ok_mem = peak_pss <= IMPORT_MAX_PEAK_MB
        lines.append(f"import: {imp['games']} games, {imp['systems']} systems, {imp['frames']} frames in "
                     f"{imp['seconds']:.1f} s = {imp['frames_per_s']:.1f} frames/s (target >= {IMPORT_MIN_FPS:g}: "
                     f"{'ok' if ok_fps else 'MISSED'}); peak PSS of the process tree {peak_pss:.0f} MB (target <= "
                     f"{IMPORT_MAX_PEAK_MB:g}: {'ok' if ok_mem else 'MISSED'}; the RSS sum {imp['peak_mb']:.0f} MB "
                     f"over {imp['peak_processes']} processes)")
        if imp.get("cpu_s"):
            lines.append(f"  CPU time of the process tree {imp['cpu_s']:.0f} s = {imp['cpu_ms_per_frame']:.1f} ms per "
                         f"frame (main process {imp.get('main_cpu_ms_per_frame', 0.0):.1f}, calibration workers "
                         f"{imp['cpu_ms_per_frame'] - imp.get('main_cpu_ms_per_frame', 0.0):.1f}; CPU-limited on "
                         f"{os.cpu_count()} cores: {1e3 * (os.cpu_count() or 1) / imp['cpu_ms_per_frame']:.0f} "
                         f"frames/s; load average at the end {', '.join(f'{v:.1f}' for v in imp['load_average'])})")
        if imp.get("stage_seconds"):
            lines.append("  stages (tqdm bars): " + ", ".join(f"{k} {v:.0f} s"
                                                              for k, v in imp["stage_seconds"].items()))
    if "demo" not in result:
        return "\n".join(lines)
    demo, scale = result["demo"], result["scale"]
    lines.append(f"served: demo {demo['systems']} systems, scale {scale['systems']} systems; "
                 f"{scale['requests']} requests per measure, {scale.get('ball_edits', 0)} ball edits")
    lines.append(f"{'measure':<24}{'demo':>10}{'scale':>10}{'ratio':>8}  {'target':<18}ok")
    for r in compare(demo, scale):
        def f(x):
            return "-" if x is None else f"{x:.1f}"
        ok = "-" if r["ok"] is None else ("ok" if r["ok"] else "MISSED")
        lines.append(f"{r['measure']:<24}{f(r['demo']):>10}{f(r['scale']):>10}{f(r['ratio']):>8}  "
                     f"{r['target']:<18}{ok}")
    if "export_first_byte_s" in scale:
        lines.append(f"export (scale): first byte after {scale['export_first_byte_s']:.1f} s, "
                     f"{scale['export_mb']:.1f} MB zip")
    lines.append("queue variants p95 ms (scale): " + ", ".join(
        f"{k} {v:.0f}" for k, v in scale.get("queue_variant_p95_ms", {}).items()))
    lines.append("queue at random depths p95 ms (scale): " + ", ".join(
        f"{k} {v:.0f}" for k, v in scale.get("queue_depth_variant_p95_ms", {}).items()))
    return "\n".join(lines)


def run(scale_dir: Optional[Path], db: Optional[Path], games: Optional[int], skip_import: bool,
        requests: int, work_dir: Path, workers: Optional[int] = None, export: bool = True,
        import_only: bool = False, images: bool = False) -> dict[str, Any]:
    """The whole benchmark (module docstring); returns the result written by ``--json``."""
    work_dir.mkdir(parents=True, exist_ok=True)
    db = Path(db) if db else work_dir / "scale" / "v3d-scale.sqlite3"
    result: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "nice": os.nice(0)}}
    if skip_import:
        if not db.is_file():
            raise BenchError(f"--skip-import: the database {db} (--db) does not exist")
    else:
        if scale_dir is None:
            raise BenchError("--scale-dir is required unless --skip-import is given")
        tree = Path(scale_dir)
        if games is not None or images:
            tree = subset_tree(Path(scale_dir), games or len(game_dirs(tree)),
                               work_dir / "subset" / Path(scale_dir).name,
                               images=images)
        else:
            game_dirs(tree)  # a clear error for a wrong folder
        print(f"importing {tree} into {db} ...", flush=True)
        result["import"] = asdict(run_import(tree, db, workers))
        if import_only:
            return result
    print("building the demo database ...", flush=True)
    demo_db = build_demo_db(work_dir)
    for name, path in (("demo", demo_db), ("scale", db)):
        print(f"serving and measuring the {name} database ...", flush=True)
        with Server(path) as server:
            result[name] = measure_server(server.base_url, requests=requests, export=export, headers=server.headers)
    return result


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scale-dir", type=Path, help="The unpacked soccernet-v3-scale tree.")
    p.add_argument("--games", type=int, help="Import only the first N games.")
    p.add_argument("--db", type=Path, help="Scale database path (kept; default: under --work-dir).")
    p.add_argument("--skip-import", action="store_true", help="Reuse the database given by --db.")
    p.add_argument("--requests", type=int, default=100, help="Requests per measure (default 100).")
    p.add_argument("--workers", type=int, help="Calibration processes of the import (default: the setting).")
    p.add_argument("--no-export", action="store_true", help="Skip the export measure.")
    p.add_argument("--work-dir", type=Path, help="Folder for the demo database and the subset (default: temporary).")
    p.add_argument("--json", type=Path, help="Write the figures as JSON here.")
    p.add_argument("--import-only", action="store_true", help="Measure the import only (no demo, no requests).")
    p.add_argument("--with-images", action="store_true", help="Give each game of the (copied) set a Frames-v3.zip of "
                                                              "PNGs at the labelled sizes, so the import checks them.")
    args = p.parse_args(argv)
    if args.games is not None and args.games < 1:
        p.error("--games must be at least 1")
    if args.import_only and args.skip_import:
        p.error("--import-only and --skip-import exclude each other")
    if args.requests < 1:
        p.error("--requests must be at least 1")
    tmp = None
    work_dir = args.work_dir
    if work_dir is None:
        tmp = tempfile.TemporaryDirectory(prefix="v3d-scale-")
        work_dir = Path(tmp.name)
    try:
        result = run(args.scale_dir, args.db, args.games, args.skip_import, args.requests, work_dir,
                     args.workers, export=not args.no_export, import_only=args.import_only,
                     images=args.with_images)
    except BenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        if tmp is not None:
            tmp.cleanup()
    print(format_report(result))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
        print(f"figures written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
