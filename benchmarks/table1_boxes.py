"""The paper's Table 1 through the service (issue 19): each synthetic SoccerNet-v3 dev set imported with v3d's own
calibration into a fresh SQLite file, the truth's ``precise_box`` of every view written as a precise-box CSV and
stored (``app.services.evaluation.boxes.store_precise_boxes``; the ISSIA dev sequence likewise, its views named
``cam<k>_<frame index>``, its labels points: no original box), then ``evaluate_boxes`` over every system
(``--all``): IoU and size error of the original (imported), optimised and refined boxes, and the original row
computed again from the truth file alone (``truth_original``: its ``annotated_box`` against its ``precise_box``, no
v3d code), which the service's original row must equal.

Run: ``.venv/bin/python benchmarks/table1_boxes.py [--shared ../shared] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.core.config import Settings
from app.core.paths import SHARED_DIR
from app.datasets.csv_cells import inert_row
from app.db.session import make_engine, make_session_factory, upgrade_database
from app.services.evaluation.boxes import PRECISE_COLUMNS, evaluate_boxes, store_precise_boxes
from app.services.transfer.importing import import_soccernet_v3

SETS = ("soccernet-v3-dev", "soccernet-v3-dev-large", "issia-dev")


def precise_csv(truth_path: Path, out: Path) -> Path:
    """The precise-box CSV of every view of a truth file that has a ``precise_box``."""
    raw = json.loads(truth_path.read_text())
    with out.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(PRECISE_COLUMNS)
        for g in raw["games"]:
            for s in g["systems"]:
                for v in s["views"]:
                    if v.get("precise_box"):
                        w.writerow([*inert_row([g["league"], g["season"], g["match"], v["image"]]), *v["precise_box"]])
    return out


def issia_precise_csv(truth_path: Path, sequence: str, out: Path) -> Path:
    """The precise-box CSV of an ISSIA truth file: one row per labelled view with a ``precise_box``, the view named
    ``cam<k>_<frame index, 6 digits>`` in the game ``issia/sequences/<sequence>`` (``KindPolicy.image_name``)."""
    from app.services.issia.sequences import LEAGUE, SEASON

    raw = json.loads(truth_path.read_text())
    with out.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(PRECISE_COLUMNS)
        for f in raw["frames"]:
            for cam, v in f["cams"].items():
                if v.get("precise_box"):
                    w.writerow([*inert_row([LEAGUE, SEASON, sequence, f"cam{cam}_{f['frame']:06d}"]),
                                *v["precise_box"]])
    return out


def truth_original(truth_path: Path) -> dict:
    """The original row computed from the truth file alone, with no v3d code: every view with an ``annotated_box``
    (the box its label was drawn with) and a ``precise_box``, IoU and ``|diag - diag_precise| / diag_precise`` (%)
    written out here, means over those views; what ``evaluate_boxes``' original row must give."""
    ious, sizes = [], []
    for g in json.loads(truth_path.read_text()).get("games", []):
        for s in g["systems"]:
            for v in s["views"]:
                a, b = v.get("annotated_box"), v.get("precise_box")
                if not a or not b:
                    continue
                iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
                ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
                union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - iw * ih
                ious.append(iw * ih / union)
                da = ((a[2] - a[0]) ** 2 + (a[3] - a[1]) ** 2) ** 0.5
                db = ((b[2] - b[0]) ** 2 + (b[3] - b[1]) ** 2) ** 0.5
                sizes.append(100.0 * abs(da - db) / db)
    if not ious:  # ISSIA labels are points: no original box
        return {"n": 0, "iou": None, "size_error_pct": None}
    return {"n": len(ious), "iou": sum(ious) / len(ious), "size_error_pct": sum(sizes) / len(sizes)}


def run(shared: Path, workdir: Path, sets=SETS) -> dict:
    results = {}
    for name in sets:
        root = shared / "data" / "synthetic" / name
        if not root.is_dir():
            continue
        url = f"sqlite:///{workdir / (name + '.sqlite3')}"
        upgrade_database(url)
        engine = make_engine(url)
        settings = Settings(database_url=url, calibration_workers=0)
        truth = shared / "data" / "synthetic" / f"{name}.truth.json"
        with make_session_factory(engine)() as session:
            if name.startswith("issia"):
                from app.services.issia.sequences import import_issia

                import_issia(session, root, settings)
                session.commit()
                csv_path = issia_precise_csv(truth, root.name, workdir / f"{name}.precise.csv")
            else:
                import_soccernet_v3(session, root, settings)
                session.commit()
                csv_path = precise_csv(truth, workdir / f"{name}.precise.csv")
            store_precise_boxes(session, csv_path)
            results[name] = evaluate_boxes(session, include_all=True, ball_diameter_m=settings.ball_diameter_m)
            results[name]["truth_original"] = truth_original(truth)
        engine.dispose()
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--shared", type=Path, default=SHARED_DIR)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--sets", default=",".join(SETS))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        results = run(args.shared, Path(tmp), tuple(args.sets.split(",")))
    for name, r in results.items():
        print(f"{name}: {r['views']} views with a precise box")
        for k in ("original", "optimised", "refined", "truth_original"):
            if r[k]["n"]:
                print(f"  {k:<14} n={r[k]['n']:<5} IoU {r[k]['iou']:.3f}  size error {r[k]['size_error_pct']:.1f} %")
            else:
                print(f"  {k:<14} n=0")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
