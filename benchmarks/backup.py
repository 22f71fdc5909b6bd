"""Backup benchmark: ``v3d backup`` and ``v3d restore`` of the SoccerNet-v3-size database, and the edits of 20
annotators while a backup runs (``benchmarks/BACKUP.md``).

One run, on a copy of a scale database (``benchmarks/scale.py --import-only --db DB`` makes one from
``shared/data/synthetic/soccernet-v3-scale.tar.gz``: 400 games, 12,800 systems):

1. ``v3d backup`` of it (a subprocess: its wall time, the peak memory of its process tree, the archive's size) and
   ``v3d restore --verify-only`` of the archive;
2. ``v3d restore`` of the archive into a fresh SQLite file and folder, and, with ``--pg-url``, into a fresh
   PostgreSQL database on that server (wall time, peak memory), each checked to hold every row of the source;
3. ``--pairs`` interleaved pairs of edit loads on the served copy (``v3d serve --workers 2``): ``--clients``
   annotators sending ``--edits`` ball edits in all (``benchmarks/load.py``'s clients, ``If-Match`` on), once alone and
   once while a ``v3d backup`` of the served database runs, alternating which goes first; the p95 of each, their
   ratio, and every answer's status (a failed edit is one answered 5xx or not at all).

Usage (from the checkout; after a scale import)::

    .venv/bin/python benchmarks/backup.py --db /work/scale/v3d-scale.sqlite3 \\
        --pg-url postgresql+psycopg://postgres@127.0.0.1:5432/test --json backup.json
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.load import LoadReport, labelled_views, run_clients, served
from benchmarks.scale import BenchError, TreeMemorySampler, bench_token, sqlite_url, v3d_command


def timed_command(args: list[str], env: dict[str, str]) -> dict[str, Any]:
    """Run ``v3d ARGS`` with ``env``; its wall time (s), peak RSS and PSS of its tree (MB) and exit status.

    Raises:
        BenchError: it exited non-zero (its error output named).
    """
    t0 = time.monotonic()
    proc = subprocess.Popen([*v3d_command(), *args], env={**os.environ, **env}, cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    with TreeMemorySampler(proc.pid, 0.05) as sampler:
        out, err = proc.communicate()
    seconds = time.monotonic() - t0
    if proc.returncode != 0:
        raise BenchError(f"v3d {' '.join(args)} exited {proc.returncode}: {err.strip()[-500:]}")
    return {"seconds": round(seconds, 2), "peak_rss_mb": round(sampler.peak_mb, 1),
            "peak_pss_mb": round(sampler.peak_pss_mb, 1), "cpu_s": round(sampler.cpu_s, 2), "output": out.strip()}


def row_counts(url: str) -> dict[str, int]:
    """Every table's rows (of v3d's models) in the database at ``url``."""
    import sqlalchemy as sa

    from app.db.models import Base
    from app.db.session import make_engine

    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return {t.name: int(conn.execute(sa.select(sa.func.count()).select_from(t)).scalar_one())
                    for t in Base.metadata.sorted_tables}
    finally:
        engine.dispose()


def fresh_pg(server_url: str) -> str:
    """A new empty database ``v3d_backup_<hex>`` on the server of ``server_url``; its URL."""
    import sqlalchemy as sa

    name = f"v3d_backup_{uuid.uuid4().hex[:8]}"
    engine = sa.create_engine(server_url, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    engine.dispose()
    return sa.make_url(server_url).set(database=name).render_as_string(hide_password=False)


def drop_pg(server_url: str, url: str) -> None:
    import sqlalchemy as sa

    name = sa.make_url(url).database
    engine = sa.create_engine(server_url, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
    engine.dispose()


def edit_load(base: str, token: str, clients: int, edits: int, backup_env: Optional[dict[str, str]],
              archive: Path) -> dict[str, Any]:
    """``clients`` annotators' ``edits`` ball edits on the server at ``base``; with ``backup_env``, a ``v3d backup``
    of its database to ``archive`` started with them (its time reported). The load's summary."""
    import httpx

    report = LoadReport(clients, edits, 2, "sqlite")
    with httpx.Client(base_url=base, timeout=60.0, headers={"Authorization": f"Bearer {token}"}) as http:
        views = labelled_views(http)
    backup = None
    t0 = time.monotonic()
    if backup_env is not None:
        backup = subprocess.Popen([*v3d_command(), "backup", str(archive)], env={**os.environ, **backup_env},
                                  cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    run_clients(base, views, report, [token] * clients, True, False, 60.0, 1800.0)
    out = report.summary()
    if backup is not None:
        _, err = backup.communicate()
        out["backup_exit"] = backup.returncode
        out["backup_s"] = round(time.monotonic() - t0, 1)
        if backup.returncode != 0:
            out["backup_error"] = err.strip()[-300:]
    return out


def run(db: Path, pg_url: Optional[str], clients: int, edits: int, pairs: int, work: Path) -> dict[str, Any]:
    """The whole run (module docstring); the figures."""
    source = work / "source.sqlite3"
    shutil.copyfile(db, source)
    env = {"V3D_DATABASE_URL": sqlite_url(source), "V3D_STORAGE_URL": (work / "store").as_uri(),
           "V3D_JOBS_DIR": str(work / "jobs")}
    out: dict[str, Any] = {"source_rows": row_counts(sqlite_url(source)),
                           "source_mb": round(source.stat().st_size / 2**20, 1)}
    archive = work / "scale-backup.zip"
    out["backup"] = timed_command(["backup", str(archive)], env)
    out["archive_mb"] = round(archive.stat().st_size / 2**20, 1)
    out["verify"] = timed_command(["restore", "--verify-only", str(archive)], env)
    target = work / "restored.sqlite3"
    sqlite_env = {"V3D_DATABASE_URL": sqlite_url(target), "V3D_STORAGE_URL": (work / "store-r").as_uri(),
                  "V3D_JOBS_DIR": str(work / "jobs-r")}
    out["restore_sqlite"] = timed_command(["restore", str(archive)], sqlite_env)
    out["restore_sqlite"]["rows_equal"] = row_counts(sqlite_url(target)) == out["source_rows"]
    if pg_url:
        url = fresh_pg(pg_url)
        try:
            pg_env = {"V3D_DATABASE_URL": url, "V3D_STORAGE_URL": (work / "store-pg").as_uri(),
                      "V3D_JOBS_DIR": str(work / "jobs-pg")}
            out["restore_postgresql"] = timed_command(["restore", str(archive)], pg_env)
            out["restore_postgresql"]["rows_equal"] = row_counts(url) == out["source_rows"]
        finally:
            drop_pg(pg_url, url)
    token = bench_token(source)
    loads: list[dict[str, Any]] = []
    with served(sqlite_url(source), 2) as base:
        for pair in range(pairs):
            order = (False, True) if pair % 2 == 0 else (True, False)
            for with_backup in order:
                figures = edit_load(base, token, clients, edits, env if with_backup else None,
                                    work / f"during-{pair}.zip")
                loads.append({"pair": pair, "with_backup": with_backup, **figures})
    out["loads"] = loads
    alone = [x["p95_ms"] for x in loads if not x["with_backup"]]
    during = [x["p95_ms"] for x in loads if x["with_backup"]]
    out["p95_alone_ms"], out["p95_during_backup_ms"] = alone, during
    out["p95_ratio_per_pair"] = [round(d / a, 2) for a, d in zip(alone, during, strict=True)]
    out["failed_edits"] = sum(x["5xx"] + x["error"] for x in loads)
    with sqlite3.connect(source) as conn:
        out["integrity"] = conn.execute("PRAGMA integrity_check").fetchone()[0]
    return out


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--db", type=Path, required=True, help="A scale database (benchmarks/scale.py --import-only).")
    p.add_argument("--pg-url", help="A PostgreSQL server to restore into too (a fresh database, dropped after).")
    p.add_argument("--clients", type=int, default=20)
    p.add_argument("--edits", type=int, default=400, help="Edits of one load, all clients together.")
    p.add_argument("--pairs", type=int, default=2, help="Interleaved pairs of loads (alone, during a backup).")
    p.add_argument("--work-dir", type=Path, help="Where the copies and archives go (default: temporary, removed).")
    p.add_argument("--json", type=Path, help="Write the figures here.")
    args = p.parse_args(argv)
    work = args.work_dir or Path(tempfile.mkdtemp(prefix="v3d-backup-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        result = run(args.db, args.pg_url, args.clients, args.edits, args.pairs, work)
    except BenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    finally:
        if args.work_dir is None:
            shutil.rmtree(work, ignore_errors=True)
    text = json.dumps(result, indent=1)
    print(text)
    if args.json:
        args.json.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
