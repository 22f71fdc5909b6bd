"""Yield on the shared doubts sets (``benchmarks/YIELD.md``): ``v3d stats yield --truth`` of each set as imported
(labels only, no predictions, no fixes): systems with a 3D ball under the paper's rules and under v3d's, and how many
are right within 0.5 m. The detector sets' figures (with and without predictions, before and after a pass of fixes)
come from ``benchmarks/detector_fill.py``.

Each set is imported once with ``v3d import soccernet-v3`` into a cached SQLite database (``--db-dir``, shared with
``benchmarks/doubts_seeds.py``'s cache layout), then ``v3d stats yield`` runs on it as a user would.

Run: ``.venv/bin/python benchmarks/ball_yield.py [--sets dev-large seed-201 ...] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.doubts_seeds import SETS, V3D, _run, template


def truth_of(name: str) -> Path:
    """The truth file beside the set's tree."""
    tree = SETS[name]
    return tree.with_name(tree.name + ".truth.json")


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="*", default=list(SETS))
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-doubts-seeds"))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    report: dict[str, Any] = {}
    for name in args.sets:
        db = template(name, args.db_dir)
        out = args.db_dir / f"{name}.yield.json"
        r = _run(V3D + ["stats", "yield", "--truth", str(truth_of(name)), "--json", str(out)], f"sqlite:///{db}")
        report[name] = json.loads(out.read_text())
        print(f"[{name}] " + " | ".join(r.stdout.strip().splitlines()[:2]), flush=True)
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
