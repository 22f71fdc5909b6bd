"""Releases at scale: make, diff and export releases of a SoccerNet-v3-size database (12,800 systems).

One run on a copy of a scale database (``benchmarks/scale.py --import-only --db DB`` makes one; the copy leaves it as
it was):

1. every system is accepted (one SQL statement each for decisions and the queue's copy of the status);
2. release ``r1`` is made (``app.services.releases.content.create_release``): wall and CPU time, documents stored
   and their compressed bytes;
3. ``--changes`` systems get a ball moved 3 px in one view and are recomputed (``recompute_system``), and as many
   others are rejected; release ``r2`` is made: time, and the storage it added (rows and new documents);
4. the diff ``r1`` -> ``r2`` (``app.services.releases.diff.diff_releases``): time, and its counts checked against
   what was changed;
5. the SoccerNet-v3D export without images, of the database now (accepted systems) and of ``r2``, each written
   to a zip (``exports.files.write_export_zip``) ``--repeats`` times, interleaved: wall and CPU time (CPU is robust to
   the other jobs of a shared machine), and the release's zip written twice compared byte for byte.

Usage::

    .venv/bin/python benchmarks/release_scale.py --db /tmp/rel-scale/v3d-scale.sqlite3 [--changes 128] [--repeats 2]
        [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import random
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import BallLabel, Frame, ReleaseDocument, ReleaseSystem, ReviewDecision, ReviewStatus, System
from app.db.session import make_engine, upgrade_database
from app.services.derivation.recompute import recompute_system
from app.services.exports.files import write_export_zip
from app.services.releases.content import create_release
from app.services.releases.diff import diff_releases


def timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``fn()``, its wall time and its CPU time (this process), seconds."""
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def accept_all(session: Session) -> int:
    """Every system accepted (its decision row made where missing); how many systems."""
    missing = sa.select(System.id, sa.literal(ReviewStatus.ACCEPTED.value), sa.literal(""), sa.literal(False),
                        sa.literal(ReviewStatus.PENDING.value), sa.literal("")).where(
        ~sa.exists().where(ReviewDecision.system_id == System.id))
    session.execute(sa.insert(ReviewDecision).from_select(
        ["system_id", "status", "comment", "excluded", "calibration_status", "calibration_comment"], missing))
    session.execute(sa.update(ReviewDecision).where(ReviewDecision.system_id.is_not(None))
                    .values(status=ReviewStatus.ACCEPTED))
    session.execute(sa.update(System).values(review_status=ReviewStatus.ACCEPTED))
    session.commit()
    return int(session.scalar(sa.select(sa.func.count(System.id))) or 0)


def storage(session: Session) -> dict[str, int]:
    """Documents stored and their compressed bytes; release_systems rows."""
    docs, size = session.execute(sa.select(sa.func.count(), sa.func.coalesce(sa.func.sum(
        sa.func.length(ReleaseDocument.body)), 0))).one()
    rows = session.scalar(sa.select(sa.func.count()).select_from(ReleaseSystem)) or 0
    return {"documents": int(docs), "document_bytes": int(size), "system_rows": int(rows)}


def change_systems(session: Session, settings: Settings, n: int, rng: random.Random) -> tuple[list[int], list[int]]:
    """Move one labelled view's ball 3 px in ``n`` systems (recomputed) and reject ``n`` others; their ids."""
    labelled = list(session.scalars(sa.select(Frame.system_id).join(BallLabel, BallLabel.frame_id == Frame.id)
                                    .where(BallLabel.box.is_not(None)).distinct()))
    picked = rng.sample(sorted(labelled), 2 * n)
    moved, rejected = sorted(picked[:n]), sorted(picked[n:])
    for sid in moved:
        system = session.get(System, sid)
        assert system is not None
        frame = next(f for f in system.frames if f.ball_label is not None and f.ball_label.box is not None)
        box = list(frame.ball_label.box)  # type: ignore[union-attr]  # checked just above
        frame.ball_label.box = [box[0] + 3.0, box[1], box[2] + 3.0, box[3]]  # type: ignore[union-attr]  # as above
        recompute_system(session, system, settings)
        session.commit()
    session.execute(sa.update(ReviewDecision).where(ReviewDecision.system_id.in_(rejected))
                    .values(status=ReviewStatus.REJECTED))
    session.execute(sa.update(System).where(System.id.in_(rejected)).values(review_status=ReviewStatus.REJECTED))
    session.commit()
    return moved, rejected


def run(db: Path, changes: int, repeats: int, seed: int = 0) -> dict[str, Any]:
    """The whole benchmark (module docstring) on a copy of ``db``; the figures."""
    work = Path(tempfile.mkdtemp(prefix="v3d-release-scale-"))
    try:
        copy = work / "scale.sqlite3"
        shutil.copyfile(db, copy)
        url = f"sqlite:///{copy}"
        upgrade_database(url)
        settings = Settings(database_url=url, calibration_workers=1)
        session = Session(make_engine(url))
        out: dict[str, Any] = {"systems": accept_all(session)}
        r1, wall, cpu = timed(lambda: create_release(session, "r1"))
        out["r1"] = {"wall_s": wall, "cpu_s": cpu, "systems": r1.systems, "views": r1.views, **storage(session)}
        before = storage(session)
        moved, rejected = change_systems(session, settings, changes, random.Random(seed))
        r2, wall, cpu = timed(lambda: create_release(session, "r2"))
        after = storage(session)
        out["r2"] = {"wall_s": wall, "cpu_s": cpu, "systems": r2.systems, "views": r2.views,
                     "added_documents": after["documents"] - before["documents"],
                     "added_document_bytes": after["document_bytes"] - before["document_bytes"],
                     "added_system_rows": after["system_rows"] - before["system_rows"]}
        diff, wall, cpu = timed(lambda: diff_releases(session, "r1", "r2"))
        out["diff"] = {"wall_s": wall, "cpu_s": cpu, "added": len(diff.added), "removed": len(diff.removed),
                       "changed": len(diff.changed),
                       "removed_as_rejected": sorted(s["system_id"] for s in diff.removed) == rejected,
                       "changed_as_moved": sorted(s["system_id"] for s in diff.changed) == moved,
                       "moved_m_positive": sum(1 for s in diff.changed if (s["ball3d_moved_m"] or 0) > 0),
                       "moved_m_null": sum(1 for s in diff.changed if s["ball3d_moved_m"] is None),
                       "changed_views_label": sum(1 for s in diff.changed for v in s["views"]
                                                  if "label" in v["changes"])}
        exports: dict[str, list[dict[str, float]]] = {"live": [], "release": []}
        blobs = []
        for k in range(repeats):
            for what, release in (("live", None), ("release", "r2")):
                target = work / f"{what}-{k}.zip"
                report, wall, cpu = timed(lambda t=target, r=release: write_export_zip(  # type: ignore[misc]  # bound defaults
                    session, "soccernet-v3d", t, False, settings, images=False, release=r))
                exports[what].append({"wall_s": wall, "cpu_s": cpu, "bytes": report["bytes"]})
                if release:
                    blobs.append(target.read_bytes())
        out["export"] = {what: {"wall_s": min(r["wall_s"] for r in runs), "cpu_s": min(r["cpu_s"] for r in runs),
                                "bytes": runs[0]["bytes"]} for what, runs in exports.items()}
        out["export"]["release_cpu_ratio"] = out["export"]["release"]["cpu_s"] / out["export"]["live"]["cpu_s"]
        out["export"]["release_zips_identical"] = len(set(blobs)) == 1
        session.close()
        return out
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, required=True, help="A scale database (benchmarks/scale.py --import-only).")
    p.add_argument("--changes", type=int, default=128, help="Systems moved (and as many rejected) before r2.")
    p.add_argument("--repeats", type=int, default=2, help="Exports of each kind (the fastest is reported).")
    p.add_argument("--json", type=Path, help="Write the figures as JSON here.")
    args = p.parse_args(argv)
    figures = run(args.db, args.changes, args.repeats)
    text = json.dumps(figures, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
