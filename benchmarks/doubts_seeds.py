"""Doubts on many seeds (issue 18): every set imported by the service, judged by today's code, scored by the
shared tools that define the targets.

For each set (dev-large and the five fresh seeds ``doubts-seeds/seed-201..205``, each with its truth file):

1. import it once with ``v3d import soccernet-v3`` into a cached SQLite database (``--db-dir``; the import
   calibrates every frame, the slow part, about a minute a set on this machine);
2. copy that database and run ``v3d recompute`` (admission, mirror flags, triangulation, doubts with the
   code of this tree), then ``v3d doubts --json``;
3. score the JSON with ``../shared/tools/doubts_eval.py TRUTH DOUBTS`` (caught, culprit, clean systems with a
   label doubt, out-of-frame views called missing, near-duplicates, suggested-box centre error);
4. serve a fresh copy (``v3d serve`` on a port of 8500-8549), add an admin, and run
   ``../shared/tools/curation_yield.py`` (one pass of every label doubt's fix through the API, then each
   system's 3D ball against the truth; ``--no-yield`` skips it);
5. time ``app.geometry.doubts.judge_system`` on every system of the recomputed copy, in process (CPU time per
   system: median, p95, max), so that a slower judge shows on a quiet machine.

Prints one line per set and figure, and the pooled near-duplicates and suggested-box median (the targets
pool them over the five seeds). ``--json OUT`` writes every figure. Thresholds: the seeds that chose them are
listed in ``THRESHOLD_SEEDS`` (the others are held out); the README quotes both groups.

Run (one command, every figure of every set): ``.venv/bin/python benchmarks/doubts_seeds.py [--sets dev-large
seed-201 ...] [--no-yield] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from statistics import median
from typing import Any, Iterator, Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.core.paths import SHARED_DIR

SYNTH = SHARED_DIR / "data" / "synthetic"
SETS: dict[str, Path] = {"dev-large": SYNTH / "soccernet-v3-dev-large",
                         **{f"seed-{n}": SYNTH / "doubts-seeds" / f"seed-{n}" for n in range(201, 206)}}
#: Sets whose figures chose thresholds and rules (dev-large: every threshold of ``DoubtSettings``; seeds
#: 201-202: the rules of issue 18 (vote weights, few-line helpers, the one-view missing-ball chance); seed 203
#: was looked at for the one-view rule of a ball in the air, so it is no longer held out); 204 and 205 are held out.
#: The triangulation's view weights (``MIN_PAIR_WEIGHT``, ``benchmarks/triangulation_weights.py``) were chosen on
#: dev-large and seeds 201-202 only.
THRESHOLD_SEEDS: tuple[str, ...] = ("dev-large", "seed-201", "seed-202", "seed-203")
TOOLS = SHARED_DIR / "tools"
V3D = [str(Path(sys.executable).parent / "v3d")]


#: The caller's settings every command of a run gets too (the rule that makes the stored 3D ball and its bound), so
#: that ``V3D_BALL_RULE=evidence .venv/bin/python benchmarks/...`` measures that rule end to end; every other ``V3D_``
#: variable of the caller (a database URL above all) is left out.
PASSED_SETTINGS: tuple[str, ...] = ("V3D_BALL_RULE", "V3D_BALL_MAX_SIGMA_M")


def _env(url: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("V3D_") or k in PASSED_SETTINGS}
    env.update(V3D_DATABASE_URL=url, V3D_DATA_ROOT=str(SHARED_DIR / "data"), PYTHONPATH=str(ROOT))
    return env


def _run(args: list[str], url: str, **kw: Any) -> subprocess.CompletedProcess:
    r = subprocess.run(args, cwd=ROOT, env=_env(url), capture_output=True, text=True, **kw)
    if r.returncode not in (0, 1) or (r.returncode == 1 and "doubts_eval" not in " ".join(args)
                                       and "curation_yield" not in " ".join(args)):
        raise RuntimeError(f"{' '.join(args)} failed ({r.returncode}): {r.stderr[-2000:]}")
    return r


def template(name: str, db_dir: Path) -> Path:
    """The cached database of set ``name`` as imported (imported when absent)."""
    db_dir.mkdir(parents=True, exist_ok=True)
    path = db_dir / f"{name}.sqlite3"
    if not path.exists():
        part = path.with_suffix(".part")
        part.unlink(missing_ok=True)
        t0 = time.perf_counter()
        _run(V3D + ["import", "soccernet-v3", str(SETS[name])], f"sqlite:///{part}")
        print(f"[{name}] imported in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        part.rename(path)
    return path


def working_copy(name: str, db_dir: Path, tag: str) -> str:
    """A copy of the set's database recomputed by this tree's code; its URL."""
    src = template(name, db_dir)
    dst = db_dir / f"{name}.{ROOT.name}-{tag}.sqlite3"
    for extra in (dst.with_name(dst.name + "-wal"), dst.with_name(dst.name + "-shm")):
        extra.unlink(missing_ok=True)
    shutil.copyfile(src, dst)
    url = f"sqlite:///{dst}"
    _run(V3D + ["recompute"], url)
    return url


_NUM = r"(\d+)/(\d+)"


def parse_eval(line: str) -> dict[str, Any]:
    """The counts of a ``doubts_eval.py`` line."""
    def pair(label: str) -> list[int] | None:
        m = re.search(label + r"\s+" + _NUM, line)
        return [int(m.group(1)), int(m.group(2))] if m else None
    m = re.search(r"median ([\d.]+|inf) px@1920", line)
    return {"caught": pair("caught"), "culprit": pair("culprit named"), "clean_flagged": pair("label doubt"),
            "out_of_frame_missing": pair("wrongly called missing"), "near_duplicates": pair("near-duplicates named"),
            "suggestion_median_px": float(m.group(1)) if m else None, "line": line.strip()}


def judge(name: str, db_dir: Path, out_dir: Path) -> dict[str, Any]:
    """Recompute, export the doubts and score them with the shared evaluator."""
    url = working_copy(name, db_dir, "judge")
    doubts = out_dir / f"{name}.doubts.json"
    _run(V3D + ["doubts", "--json", str(doubts)], url)
    truth = SETS[name].with_name(SETS[name].name + ".truth.json")
    r = _run([sys.executable, str(TOOLS / "doubts_eval.py"), str(truth), str(doubts)], url)
    res = parse_eval(r.stdout)
    res["suggestion_errors_px"] = suggestion_errors(json.loads(truth.read_text()), json.loads(doubts.read_text()))
    res["judge_time"] = judge_times(url)
    return res


def suggestion_errors(truth: dict, out: dict) -> list[float]:
    """The per-case suggested-box centre errors as the evaluator measures them (for the pooled median)."""
    by = {(s["game"]["match"], s["system"]): s["doubts"] for s in out["systems"]}
    def ncal(v):
        return len(set(v["visible_line_classes"]) - set(v["dropped_line_classes"]))
    errs = []
    for g in truth["games"]:
        for s in g["systems"]:
            if s["corruption"] != "no_ball":
                continue
            cv = next(v for v in s["views"] if v["image"] == s["corrupted_view"])
            others = [v for v in s["views"] if v is not cv and v.get("annotated_box") and ncal(v) >= 4]
            if ncal(cv) < 4 or len(others) < 2:
                continue
            err = float("inf")
            for d in by.get((g["match"], s["action"]), []):
                box = (d.get("suggestion") or {}).get("box") if d["kind"] == "ball_missing" else None
                if box and d.get("frame") == cv["image"]:
                    pb = cv["precise_box"]
                    e = ((box[0] + box[2] - pb[0] - pb[2]) ** 2 + (box[1] + box[3] - pb[1] - pb[3]) ** 2) ** 0.5 / 2
                    err = min(err, e * 1920 / cv["width"])
            errs.append(err)
    return errs


def judge_times(url: str) -> dict[str, float]:
    """CPU time of ``judge_system`` per system of the database at ``url`` (ms: median, p95, max, systems)."""
    import numpy as np
    import sqlalchemy as sa
    from sqlalchemy.orm import Session, selectinload

    from app.core.config import Settings
    from app.db.models import Frame, System
    from app.geometry.doubts import judge_system
    from app.services.derivation.doubts import doubt_settings, doubt_views
    settings = doubt_settings(Settings())
    times = []
    with Session(sa.create_engine(url)) as session:
        systems = session.scalars(sa.select(System).options(
            selectinload(System.frames).selectinload(Frame.calibration), selectinload(System.frames)
            .selectinload(Frame.ball_label), selectinload(System.frames).selectinload(Frame.field_lines),
            selectinload(System.frames).selectinload(Frame.review))).all()
        for system in systems:
            views = doubt_views(system)
            t0 = time.process_time()
            judge_system(views, settings)
            times.append((time.process_time() - t0) * 1e3)
    a = np.array(times)
    return {"median_ms": float(np.median(a)), "p95_ms": float(np.percentile(a, 95)), "max_ms": float(a.max()),
            "systems": len(a)}


@contextlib.contextmanager
def served_with_admin(url: str, port: int, env: dict[str, str] | None = None,
                      stderr: Any = subprocess.DEVNULL) -> Iterator[str]:
    """Serve the database ``url`` on loopback ``port`` (``v3d serve``, ``env`` added to its environment) with an admin
    ``bench`` made first; yields that admin's API token once ``/api/health`` answers, and stops the server after."""
    import httpx

    add = subprocess.run(V3D + ["users", "add", "bench", "--role", "admin", "--password-stdin"], cwd=ROOT,
                         env=_env(url), input="bench-password-long-enough\n", capture_output=True, text=True)
    if add.returncode:
        raise RuntimeError(f"users add failed: {add.stderr}")
    token = add.stdout.strip().splitlines()[-1]
    server = subprocess.Popen(V3D + ["serve", "--port", str(port)], cwd=ROOT, env={**_env(url), **(env or {})},
                              stdout=subprocess.DEVNULL, stderr=stderr)
    try:
        for _ in range(600):
            try:
                if httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            time.sleep(0.5)
        yield token
    finally:
        server.terminate()
        try:
            server.wait(timeout=30)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(timeout=30)


def curation_yield(name: str, db_dir: Path, port: int) -> dict[str, Any]:
    """Serve a fresh recomputed copy and run the shared curation-yield tool against it."""
    url = working_copy(name, db_dir, "yield")
    with served_with_admin(url, port) as token:
        truth = SETS[name].with_name(SETS[name].name + ".truth.json")
        r = _run([sys.executable, str(TOOLS / "curation_yield.py"), f"http://127.0.0.1:{port}", token, str(truth)], url)
        lines = r.stdout.strip().splitlines()
        if not lines:
            raise RuntimeError(f"curation_yield.py printed nothing: {r.stderr[-2000:]}")
        return json.loads(lines[0])


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="*", default=list(SETS), choices=list(SETS))
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-doubts-seeds"))
    ap.add_argument("--no-yield", dest="do_yield", action="store_false", help="skip curation_yield.py")
    ap.add_argument("--port", type=int, default=8500)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    report: dict[str, Any] = {"threshold_sets": list(THRESHOLD_SEEDS), "sets": {}}
    errs_pooled, nd = [], [0, 0]
    for i, name in enumerate(args.sets):
        res = judge(name, args.db_dir, args.db_dir)
        tag = "chose thresholds" if name in THRESHOLD_SEEDS else "held out"
        print(f"[{name}] ({tag}) {res['line']}", flush=True)
        jt = res["judge_time"]
        print(f"[{name}] judge_system CPU per system: median {jt['median_ms']:.2f} ms, p95 {jt['p95_ms']:.2f} ms, "
              f"max {jt['max_ms']:.1f} ms over {jt['systems']} systems", flush=True)
        if name != "dev-large":
            errs_pooled += res["suggestion_errors_px"]
            nd = [nd[0] + res["near_duplicates"][0], nd[1] + res["near_duplicates"][1]]
        if args.do_yield:
            y = curation_yield(name, args.db_dir, args.port + i)
            res["yield"] = y
            a = y["after"]
            share = a["corrupted_right"] / max(a["corrupted_with_ball"], 1)
            print(f"[{name}] curation yield: made right {y['made_right']}, made wrong {y['made_wrong']} "
                  f"{y['made_wrong_systems']}; corrupted systems right {y['before']['corrupted_right']} -> "
                  f"{a['corrupted_right']} of {a['corrupted_with_ball']} with a ball ({share:.0%}); fixes {y['fixes']}",
                  flush=True)
        report["sets"][name] = res
    if errs_pooled:
        report["pooled_seeds"] = {"near_duplicates": nd, "suggestion_median_px": median(errs_pooled),
                                  "suggestions": len(errs_pooled)}
        print(f"[seeds pooled] near-duplicates named {nd[0]}/{nd[1]}; suggested-box centre median "
              f"{median(errs_pooled):.1f} px@1920 over {len(errs_pooled)} cases")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
