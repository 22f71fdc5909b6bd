"""The SoccerNet-v3 import's time against another checkout's, interleaved in one run.

Each run is ``v3d import soccernet-v3 TREE`` into a fresh SQLite file, a subprocess (``benchmarks/scale.py``'s
:func:`~scale.run_import`: wall time, CPU of the process tree and of its main process, peak RSS summed over the tree,
and peak PSS summed over it: shared pages counted once, what the tree holds, :class:`~scale.TreeMemorySampler`), with
``PYTHONPATH`` set to the checkout it runs: ``--old`` (e.g. ``git -C /work/main archive 158795d | tar -x -C DIR``) and
``--new`` (default: this checkout). The runs alternate old, new, new, old, ... (``--pairs`` pairs), so that a change
of the machine's load weighs on both; a table of every run and the medians' ratio new / old is printed.

Usage::

    nice -n 10 .venv/bin/python benchmarks/import_interleaved.py --tree SCALE_DIR --old OLD_CHECKOUT \\
        [--games N] [--pairs 2] [--work-dir DIR] [--workers N]

``--tree`` is the unpacked ``soccernet-v3-scale.tar.gz`` (or any SoccerNet-v3 tree); ``--games N`` imports the first
N games (copied under ``--work-dir``, as ``scale.py --games`` does).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from scale import ImportFigures, run_import, subset_tree  # noqa: E402  # benchmarks/ on the path above


def order(pairs: int) -> list[str]:
    """Which checkout each run uses: old, new, new, old, old, new, ... (each pair's order flipped in turn)."""
    out: list[str] = []
    for k in range(pairs):
        out += ["old", "new"] if k % 2 == 0 else ["new", "old"]
    return out


def main_cpu(fig: ImportFigures) -> float:
    """CPU seconds of the import's main process (reading, storing, recomputing; not its calibration workers)."""
    return fig.main_cpu_ms_per_frame * fig.frames / 1e3


def run_in(checkout: Path, tree: Path, db: Path, workers: int | None) -> ImportFigures:
    """:func:`scale.run_import` with ``checkout``'s code (its ``PYTHONPATH``, run from its folder)."""
    return run_import(tree, db, workers, checkout=Path(checkout))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tree", type=Path, required=True, help="SoccerNet-v3 tree (the unpacked scale set).")
    p.add_argument("--old", type=Path, required=True, help="The checkout to compare against.")
    p.add_argument("--new", type=Path, default=ROOT, help="The checkout measured (default: this one).")
    p.add_argument("--games", type=int, help="Import only the first N games.")
    p.add_argument("--pairs", type=int, default=2, help="Pairs of runs (default 2: old, new, new, old).")
    p.add_argument("--workers", type=int, help="Calibration processes (default: the setting).")
    p.add_argument("--work-dir", type=Path, help="Databases and the subset (default: temporary).")
    args = p.parse_args(argv)
    work = args.work_dir or Path(tempfile.mkdtemp(prefix="v3d-interleaved-"))
    work.mkdir(parents=True, exist_ok=True)
    tree = subset_tree(args.tree, args.games, work / "tree") if args.games else args.tree
    got: dict[str, list[ImportFigures]] = {"old": [], "new": []}
    print("| run | code | wall s | tree CPU s | main CPU s | peak RSS MB (processes) | main RSS MB "
          "| peak PSS MB | main PSS MB | load average |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for k, which in enumerate(order(args.pairs), 1):
        fig = run_in(args.old if which == "old" else args.new, tree, work / f"{which}-{k}.sqlite3", args.workers)
        got[which].append(fig)
        print(f"| {k} | {which} | {fig.seconds:.1f} | {fig.cpu_s:.1f} | {main_cpu(fig):.1f} "
              f"| {fig.peak_mb:.0f} ({fig.peak_processes}) | {fig.main_rss_mb:.0f} | {fig.peak_pss_mb:.0f} "
              f"| {fig.main_pss_mb:.0f} | {fig.load_average[0]:.1f} |", flush=True)
    old, new = got["old"], got["new"]
    print(f"\n{old[0].games} games, {old[0].systems} systems, {old[0].frames} views; medians new / old:")
    for name, value in (("wall", lambda f: f.seconds), ("tree CPU", lambda f: f.cpu_s),
                        ("main CPU", main_cpu)):
        o, n = statistics.median(map(value, old)), statistics.median(map(value, new))
        print(f"- {name}: {o:.1f} -> {n:.1f} s ({n / o:.2f})")
    print(f"- peak RSS (summed over the tree): {max(f.peak_mb for f in old):.0f} -> "
          f"{max(f.peak_mb for f in new):.0f} MB")
    print(f"- peak PSS (summed over the tree): {max(f.peak_pss_mb for f in old):.0f} -> "
          f"{max(f.peak_pss_mb for f in new):.0f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
