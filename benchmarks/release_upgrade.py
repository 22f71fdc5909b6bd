"""A release made by an older v3d, served after the upgrade: its hash kept and each of its exports byte for byte the
one made before.

The older tree (default: 158795d) is unpacked with ``git archive`` and run with this checkout's Python (its
``PYTHONPATH`` the older tree, no virtual environment of its own) on a fresh SQLite database:

1. ``v3d serve --demo`` (older code): the demo imported, its account made; with ``../shared`` present, a stretch of
   the synthetic ISSIA dev sequence (frames 0-11, no videos) is imported first by the older ``v3d import issia``, so
   that the ISSIA-3D export holds rows;
2. through the API, with an API token issued to the demo account: every SoccerNet-v3 system and the ISSIA frames
   accepted, the release ``upgrade-1`` made, and exported in every format (SoccerNet-v3D with images, YOLO, COCO,
   cameras, ISSIA-3D); the downloads kept;
3. the older server stopped, its export files deleted (the jobs folder), and this checkout's ``v3d serve`` started
   on the same database (migrating it at start-up);
4. with the same token: the release read back (its hash), exported again in every format, each download compared
   byte for byte with the one made before the upgrade.

Usage::

    .venv/bin/python benchmarks/release_upgrade.py [--old 158795d] [--work /tmp/release-upgrade] [--port 18410] \
        [--new-setting V3D_EXPORT_BALL_BOX=optimised ...]

``--new-setting`` gives the upgraded server settings the older one did not have: a release's exports keep the
settings it was made with (a release made before they were recorded: its document version's values).

Prints one JSON document (per format: sizes, SHA-256 before and after, equal) and exits 1 when anything differs.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Optional

import httpx

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: Every format a release exports to, in the registry's names (``app.services.exports.formats``).
FORMATS = ("soccernet-v3d", "yolo", "coco", "cameras", "issia-3d")
RELEASE = "upgrade-1"
#: Frames of the synthetic ISSIA dev sequence imported (none without ``../shared``).
ISSIA_FRAMES = (0, 11)
_RUN = "import sys; from app.cli import main; sys.argv[0] = 'v3d'; sys.exit(main())"


def _env(tree: Path, db: Path, settings: Optional[dict[str, str]] = None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("V3D_")}
    env.update(PYTHONPATH=str(tree), V3D_DATABASE_URL=f"sqlite:///{db}", V3D_CALIBRATION_WORKERS="1")
    env.update(settings or {})
    return env


def _v3d(tree: Path, db: Path, *args: str, timeout: float = 900) -> str:
    done = subprocess.run([sys.executable, "-c", _RUN, *args], cwd=tree, env=_env(tree, db), capture_output=True,
                          text=True, timeout=timeout)
    if done.returncode != 0:
        raise RuntimeError(f"v3d {' '.join(args)} ({tree}): {done.stderr[-3000:]}")
    return done.stdout


class Server:
    """``v3d serve`` of ``tree`` on ``db``, started and waited for, stopped by its process id."""

    def __init__(self, tree: Path, db: Path, port: int, log: Path, demo: bool,
                 settings: Optional[dict[str, str]] = None) -> None:
        self.url = f"http://127.0.0.1:{port}"
        self.log = log.open("w")
        args = ["serve", "--port", str(port), *(["--demo"] if demo else [])]
        self.proc = subprocess.Popen([sys.executable, "-c", _RUN, *args], cwd=tree, env=_env(tree, db, settings),
                                     stdout=self.log, stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.monotonic() + 900
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"v3d serve ({tree}) ended: see {log}")
            try:
                if httpx.get(f"{self.url}/api/health", timeout=5).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(1)
        self.stop()
        raise RuntimeError(f"v3d serve ({tree}) did not answer: see {log}")

    def stop(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(60)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self.log.close()


def _schema(db: Path) -> str:
    """The database's migration (Alembic's revision)."""
    with sqlite3.connect(db) as con:
        return str(con.execute("SELECT version_num FROM alembic_version").fetchone()[0])


def _export(c: httpx.Client, fmt: str) -> bytes:
    job = c.post(f"/api/exports/{fmt}", json={"release": RELEASE})
    assert job.status_code == 202, (fmt, job.status_code, job.text)
    url = job.json()["url"]
    deadline = time.monotonic() + 1800
    while (state := c.get(url).json())["state"] not in ("done", "failed"):
        if time.monotonic() > deadline:
            raise RuntimeError(f"export {fmt}: still {state['state']}")
        time.sleep(0.5)
    assert state["state"] == "done", (fmt, state)
    got = c.get(state["result_url"])
    assert got.status_code == 200, (fmt, got.status_code)
    return got.content


def _accept_all(c: httpx.Client) -> dict[str, int]:
    """Accept every system of the queue (the demo's and the ISSIA stretch's: fewer than a page); how many of each
    kind."""
    page = c.get("/api/systems", params={"limit": 500, "sort": "name"}).json()
    assert page["total"] == len(page["items"]), "more systems than one page"
    kinds: dict[str, int] = {}
    for item in page["items"]:
        sid = item["id"]
        system = c.get(f"/api/systems/{sid}")
        answer = c.post(f"/api/systems/{sid}/review", json={"status": "accepted", "comment": ""},
                        headers={"If-Match": system.headers["etag"]})
        assert answer.status_code == 200, (sid, answer.text)
        kind = system.json()["kind"]
        kinds[kind] = kinds.get(kind, 0) + 1
    return kinds


def _issia_stretch(old: Path, work: Path) -> Optional[Path]:
    """The ISSIA stretch written by the older tree's own test helper (None without ``../shared``)."""
    shared = ROOT.parent / "shared"
    if not (shared / "data" / "synthetic" / "issia-dev").is_dir():
        return None
    dest = work / "issia-dev"
    code = ("import sys; from pathlib import Path; from tests.services.issia_data import write_issia_stretch; "
            f"write_issia_stretch(Path({str(shared)!r}), Path({str(dest)!r}), {ISSIA_FRAMES[0]}, {ISSIA_FRAMES[1]}, "
            "videos=False)")
    subprocess.run([sys.executable, "-c", code], cwd=old, env={**os.environ, "PYTHONPATH": str(old)}, check=True)
    return dest


def run(old_commit: str, work: Path, port: int, new_settings: Optional[dict[str, str]] = None) -> dict[str, Any]:
    """The check (module docstring); what it saw. ``new_settings``: environment settings (``V3D_*``) of the upgraded
    server only (a setting changed with the upgrade must not change the release's exports)."""
    if work.exists():
        shutil.rmtree(work)
    old = work / "old"
    old.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", old_commit], capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
    db = work / "run" / "v3d.sqlite3"
    db.parent.mkdir()
    out: dict[str, Any] = {"old": subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", old_commit],
                                                 capture_output=True, text=True, check=True).stdout.strip(),
                           "new": subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                                 capture_output=True, text=True, check=True).stdout.strip()}
    server = Server(old, db, port, work / "old-serve.log", demo=True)  # the demo loads into the empty database
    server.stop()
    stretch = _issia_stretch(old, work)
    if stretch is not None:
        _v3d(old, db, "import", "issia", str(stretch))
    server = Server(old, db, port, work / "old-serve-2.log", demo=True)
    before: dict[str, bytes] = {}
    try:
        with httpx.Client(base_url=server.url, timeout=60) as browser:
            login = browser.post("/api/auth/login", json={"name": "demo", "password": "demo"})
            login.raise_for_status()
            issued = browser.post("/api/users/demo/tokens", json={"label": "upgrade check"},
                                  headers={"X-CSRF-Token": login.json()["csrf_token"]})
        assert issued.status_code == 201, issued.text
        token = issued.json()["token"]
        c = httpx.Client(base_url=server.url, timeout=600, headers={"Authorization": f"Bearer {token}"})
        out["accepted"] = _accept_all(c)
        made = c.post("/api/releases", json={"name": RELEASE, "note": "made before the upgrade"})
        assert made.status_code == 201, made.text
        out["release"] = {k: made.json()[k] for k in ("systems", "views", "hash")}
        for fmt in FORMATS:
            before[fmt] = _export(c, fmt)
        c.close()
    finally:
        server.stop()
    schema_before = _schema(db)
    jobs = db.parent / "jobs"
    exports_before = sorted(p.name for p in (jobs / "exports").iterdir()) if (jobs / "exports").is_dir() else []
    shutil.rmtree(jobs, ignore_errors=True)  # the export files made before the upgrade are gone
    out["export_files_deleted"] = len(exports_before)
    out["new_settings"] = dict(new_settings or {})
    server = Server(ROOT, db, port, work / "new-serve.log", demo=False, settings=new_settings)  # migrates at start
    try:
        c = httpx.Client(base_url=server.url, timeout=600, headers={"Authorization": f"Bearer {token}"})
        shown = c.get(f"/api/releases/{RELEASE}")
        out["token_after_upgrade"] = shown.status_code
        assert shown.status_code == 200, shown.text
        out["hash_kept"] = shown.json()["hash"] == out["release"]["hash"]
        out["formats"] = {}
        for fmt in FORMATS:
            after = _export(c, fmt)
            (work / f"{fmt}-before.zip").write_bytes(before[fmt])
            (work / f"{fmt}-after.zip").write_bytes(after)
            out["formats"][fmt] = {"bytes": [len(before[fmt]), len(after)],
                                   "sha256_before": hashlib.sha256(before[fmt]).hexdigest()[:16],
                                   "sha256_after": hashlib.sha256(after).hexdigest()[:16],
                                   "equal": before[fmt] == after}
        c.close()
    finally:
        server.stop()
    out["schema"] = [schema_before, _schema(db)]
    out["ok"] = out["hash_kept"] and all(f["equal"] for f in out["formats"].values())
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", default="158795d", help="The commit that makes the release (default 158795d).")
    parser.add_argument("--work", type=Path, default=Path("/tmp/release-upgrade"), help="Scratch folder (emptied).")
    parser.add_argument("--port", type=int, default=18410)
    parser.add_argument("--new-setting", action="append", default=[], metavar="V3D_NAME=VALUE",
                        help="A setting of the upgraded server only (repeatable), e.g. V3D_EXPORT_BALL_BOX=optimised.")
    args = parser.parse_args()
    new_settings = dict(s.split("=", 1) for s in args.new_setting)
    if any(not k.startswith("V3D_") for k in new_settings):
        parser.error("--new-setting takes V3D_NAME=VALUE")
    result = run(args.old, args.work, args.port, new_settings)
    print(json.dumps(result, indent=1))
    return 0 if result["ok"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
