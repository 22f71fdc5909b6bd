"""Whether two imports of the same input stored the same decisions: every view's calibration and every doubt.

Two SQLite files (e.g. the ``old-N`` / ``new-N`` databases ``import_interleaved.py --work-dir`` leaves, or the same
tree imported by two checkouts) are read with plain SQL; rows are matched by their natural keys (game league,
season and match; system name; frame name), never by ids. A calibration's source, status, flags, refusal reason,
admission and JSON fields' shapes and texts must be equal; its numbers (the camera, JaC, residuals, uncertainty,
the players' fit) may differ by ``--rtol`` relative (``placement_cpu``'s measure: a vector or matrix as a whole, by its
norm). Doubt rows must be equal to the last character (kind, view, whether it accuses a label, message, evidence and
suggestion as stored). Prints the counts, the largest relative difference per field and the first rows that differ;
exits 1 when any decision differs or a number is beyond ``--rtol``.

Usage::

    .venv/bin/python benchmarks/compare_imports.py OLD.sqlite3 NEW.sqlite3 [--rtol 1e-9]
"""
from __future__ import annotations

import argparse
import json
import sqlite3
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from placement_cpu import _largest_difference  # noqa: E402  # benchmarks/ on the path above

_FRAME_KEY = """games.league, games.season, games.match, systems.name, frames.name"""
_CALIBRATIONS = f"""SELECT {_FRAME_KEY}, c.source, c.status, c.camera, c.reason, c.flags, c.residuals_px, c.jac_0005,
    c.jac_001, c.jac_002, c.admitted, c.mirror_evidence, c.uncertainty, c.players
    FROM calibrations c JOIN frames ON frames.id = c.frame_id JOIN systems ON systems.id = frames.system_id
    JOIN games ON games.id = systems.game_id"""
_DOUBTS = """SELECT games.league, games.season, games.match, systems.name, frames.name, d.kind, d.accuses_label,
    d.message, d.evidence, d.suggestion
    FROM doubts d JOIN systems ON systems.id = d.system_id JOIN games ON games.id = systems.game_id
    LEFT JOIN frames ON frames.id = d.frame_id"""
#: Calibration columns compared as they are (decisions, words); the rest are numbers or JSON with numbers.
_EXACT = ("source", "status", "reason", "admitted")
_JSON = ("camera", "flags", "residuals_px", "mirror_evidence", "uncertainty", "players")


def _calibrations(path: Path) -> dict[tuple, dict[str, Any]]:
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    con.row_factory = sqlite3.Row
    try:
        return {tuple(row)[:5]: {k: row[k] for k in row.keys()[5:]} for row in con.execute(_CALIBRATIONS)}
    finally:
        con.close()


def _doubts(path: Path) -> list[tuple]:
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        return sorted(tuple("" if v is None else v for v in row) for row in con.execute(_DOUBTS))
    finally:
        con.close()


def compare_calibrations(old: dict[tuple, dict[str, Any]], new: dict[tuple, dict[str, Any]]
                         ) -> tuple[list[tuple], dict[str, float]]:
    """The views whose calibration differs in a decision or a field's shape (or that one side lacks), and the largest
    relative difference of the numbers per field (``jac`` for the three JaC columns)."""
    differ: list[tuple] = sorted(old.keys() ^ new.keys())
    diffs: dict[str, float] = {}
    for key in sorted(old.keys() & new.keys()):
        a, b = old[key], new[key]
        same = all(a[k] == b[k] for k in _EXACT)
        same = same and all(_largest_difference(json.loads(a[k]) if a[k] is not None else None,
                                                json.loads(b[k]) if b[k] is not None else None, k, diffs)
                            for k in _JSON)
        same = same and _largest_difference([a["jac_0005"], a["jac_001"], a["jac_002"]],
                                            [b["jac_0005"], b["jac_001"], b["jac_002"]], "jac", diffs)
        if not same:
            differ.append(key)
    return differ, diffs


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("old", type=Path)
    p.add_argument("new", type=Path)
    p.add_argument("--rtol", type=float, default=1e-9, help="Largest relative difference of a number (1e-9).")
    args = p.parse_args(argv)
    old, new = _calibrations(args.old), _calibrations(args.new)
    differ, diffs = compare_calibrations(old, new)
    beyond = {k: v for k, v in diffs.items() if v > args.rtol}
    placed = sum(1 for c in new.values() if c["players"] not in (None, "null"))
    print(f"calibrations: {len(old)} / {len(new)} views ({placed} placed by players in the second); "
          f"{len(differ)} differ in a decision or a field's shape {differ[:5]}")
    print("largest relative differences: " + (", ".join(f"{k} {v:.1e}" for k, v in sorted(diffs.items())) or "none"))
    d_old, d_new = _doubts(args.old), _doubts(args.new)
    only_old = sorted(set(d_old) - set(d_new))
    only_new = sorted(set(d_new) - set(d_old))
    same_doubts = d_old == d_new
    print(f"doubts: {len(d_old)} / {len(d_new)} rows; {'equal' if same_doubts else 'DIFFER'}"
          + ("" if same_doubts else f": {len(only_old)} only in the first, {len(only_new)} only in the second, "
             f"first {(only_old or only_new)[:1]}"))
    ok = not differ and not beyond and same_doubts
    print("same decisions, numbers within the tolerance" if ok else f"NOT THE SAME (beyond {args.rtol:g}: {beyond})")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
