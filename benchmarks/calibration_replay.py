"""Replay the calibration jobs of a SoccerNet-v3 import in this one process: CPU time per job, and
results to compare between two versions of the code (issue 8's import speed).

For the first ``--games`` games of a SoccerNet-v3 tree (sorted by path, as the importer walks them)
it builds the jobs an import of a fresh database gives the calibration pool
(``app.services.calibration.first_pass``): the first pass of every frame from its lines alone
(``import_calibration.new_frame_job``), then, per game, the rig retry of the frames
``rigs.wants_rig_retry`` picks, with the rig ``rigs.game_rig`` estimates from the game's
first-pass results. Each job runs through ``calibrating.calibrate_lines``, as in a worker, timed with
this process's CPU clock (robust to other load).

Prints the CPU ms per job (mean, median, p90) of each kind, and per imported frame (rig time spread
over every frame). ``--save FILE`` pickles every job's result (``CalibrationFields`` without the time);
``--compare FILE`` checks the results against a saved run: equal (to the last bit), or the largest
differences. ``--profile FILE`` writes a cProfile of the jobs (``pstats`` or snakeviz can read it).

Usage: ``.venv/bin/python benchmarks/calibration_replay.py --scale-dir /work/scale-data/soccernet-v3-scale
--games 10 [--skip 0] [--save a.pkl | --compare a.pkl] [--profile out.prof] [--only first|rig]``
"""
from __future__ import annotations

import argparse
import cProfile
import dataclasses
import math
import pickle
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.datasets.soccernet_v3 import read_soccernet_v3
from app.db.models import SystemKind
from app.services.calibration.calibrating import calibrate_lines
from app.services.calibration.first_pass import new_frame_job
from app.services.calibration.rigs import game_rig, wants_rig_retry


def _timed(job: tuple, profiler: cProfile.Profile | None) -> tuple[CalibrationFields, float]:
    c0 = time.process_time()
    if profiler is not None:
        profiler.enable()
    fields = calibrate_lines(*job)
    if profiler is not None:
        profiler.disable()
    return fields, (time.process_time() - c0) * 1e3


def replay(scale_dir: Path, games: int, skip: int = 0, profile_first: bool = True, profile_rig: bool = True,
           profiler: cProfile.Profile | None = None) -> dict[str, Any]:
    """Run the import's calibration jobs of games ``skip .. skip + games`` (see the module docstring).

    Returns ``{"first": [(key, fields, cpu_ms)], "rig": [...], "frames": n}`` with ``key`` the
    ``(game folder, system, frame)`` of each job."""
    settings = Settings()
    labels = sorted(Path(scale_dir).rglob("Labels-v3.json"))[skip:skip + games]
    out: dict[str, Any] = {"first": [], "rig": [], "frames": 0}
    for path in labels:
        (grec,) = read_soccernet_v3(path)
        frames = [(srec, frec) for srec in grec.systems for frec in srec.frames]
        out["frames"] += len(frames)
        firsts = []
        for srec, frec in frames:
            fields, ms = _timed(new_frame_job(frec), profiler if profile_first else None)
            firsts.append(fields)
            out["first"].append(((grec.match, srec.name, frec.name), fields, ms))
        rig = game_rig(None, None, settings, extra=firsts, extra_roles=[f.role for _, f in frames])
        if not rig.positions:
            continue
        for (srec, frec), fields in zip(frames, firsts, strict=False):
            if srec.kind is SystemKind.SOCCERNET_V3 and wants_rig_retry(fields, settings):
                job = (*new_frame_job(frec)[:4], rig, new_frame_job(frec)[5])
                retried, ms = _timed(job, profiler if profile_rig else None)
                out["rig"].append(((grec.match, srec.name, frec.name), retried, ms))
    return out


def _summary(name: str, rows: list, frames: int) -> str:
    ms = [r[2] for r in rows]
    if not ms:
        return f"{name:6} 0 jobs"
    return (f"{name:6} {len(ms):5d} jobs  mean {statistics.mean(ms):7.2f}  median {statistics.median(ms):7.2f}  "
            f"p90 {sorted(ms)[int(0.9 * (len(ms) - 1))]:7.2f} CPU ms/job  = {sum(ms) / frames:6.2f} CPU ms per frame")


def _plain(fields: CalibrationFields) -> dict[str, Any]:
    return dataclasses.asdict(dataclasses.replace(fields, elapsed_ms=None))


def _differences(a: Any, b: Any, path: str = "") -> list[tuple[str, float]]:
    """Leaves of two JSON-like values that differ: ``(path, |difference|)`` (inf for a non-number)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return [(path + " keys", math.inf)]
        return [d for k in a for d in _differences(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return [(path + " length", math.inf)]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=False)) for d in _differences(x, y, f"{path}[{i}]")]
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return [] if a == b else [(path, abs(float(a) - float(b)))]
    return [] if a == b else [(path, math.inf)]


def compare(saved: dict[str, Any], now: dict[str, Any]) -> str:
    """A report of how ``now``'s results differ from ``saved``'s, job by job."""
    lines = []
    for kind in ("first", "rig"):
        old = {k: _plain(f) for k, f, _ in saved[kind]}
        new = {k: _plain(f) for k, f, _ in now[kind]}
        missing = set(old) ^ set(new)
        diffs = {k: _differences(old[k], new[k]) for k in old.keys() & new.keys()}
        changed = {k: d for k, d in diffs.items() if d}
        status = {k for k in old.keys() & new.keys() if old[k]["status"] != new[k]["status"]}
        lines.append(f"{kind}: {len(old)} saved, {len(new)} now, {len(missing)} not in both, {len(changed)} differ "
                     f"({len(status)} in status)")
        worst = sorted(((max(v for _, v in d), k, d) for k, d in changed.items()), key=lambda t: -t[0])[:8]
        for size, key, d in worst:
            lines.append(f"  {key}: largest {size:.3g} at {max(d, key=lambda t: t[1])[0]} ({len(d)} fields)")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scale-dir", type=Path, required=True)
    ap.add_argument("--games", type=int, default=10)
    ap.add_argument("--skip", type=int, default=0, help="games skipped first")
    ap.add_argument("--save", type=Path, help="pickle the results here")
    ap.add_argument("--compare", type=Path, help="compare with results saved by --save")
    ap.add_argument("--profile", type=Path, help="write a cProfile of the jobs here")
    ap.add_argument("--only", choices=("first", "rig"), help="profile only this kind of job")
    args = ap.parse_args()
    profiler = cProfile.Profile() if args.profile else None
    result = replay(args.scale_dir, args.games, args.skip, args.only in (None, "first"), args.only in (None, "rig"),
                    profiler)
    n = result["frames"]
    print(f"{args.games} games, {n} frames")
    print(_summary("first", result["first"], n))
    print(_summary("rig", result["rig"], n))
    if profiler is not None:
        profiler.dump_stats(args.profile)
    if args.save:
        args.save.write_bytes(pickle.dumps(result))
    if args.compare:
        print(compare(pickle.loads(args.compare.read_bytes()), result))


if __name__ == "__main__":
    main()
