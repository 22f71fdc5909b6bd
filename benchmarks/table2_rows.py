"""The paper's Table 2 rows from the service (issue 19): the synthetic SoccerNet-v3 dev set (v3d's own calibration)
and the ISSIA dev sequence (its given calibration) in one SQLite file, every system (``--all``), the exported ball
boxes themselves as the detections (so AP@0.5 is 1 and the rows measure field localisation alone), scored by
``app.services.evaluation.monocular`` (the reference views, ``with_cameras``, ``evaluate``) with

* the stored cameras (the "oracle" row: SoccerNet frames calibrated on their annotated lines, ISSIA's given cameras),
* the truth's cameras (``--cameras``: the layout ``v3d export cameras`` writes, one file per image; ISSIA one per
  camera, ``camera_cam<k>.json``),
* the truth's cameras with every centre moved 2 m along x.

Prints per set AP@0.5, MAE (m and %), P@2m and the views scored: SoccerNet over the whole dev set (both games fall
in the hash split's train), ISSIA on its test split (cameras 1-2) as the paper.

Run: ``.venv/bin/python benchmarks/table2_rows.py [--database-url URL] [--json OUT]`` (without a URL the two sets
are imported into a temporary file first, a few minutes).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.core.config import Settings
from app.core.paths import SHARED_DIR
from app.db.session import make_engine, make_session_factory, upgrade_database
from app.services.evaluation.monocular import reference_views
from app.services.issia.sequences import LEAGUE, SEASON
from app.services.transfer.cameras_export import camera_file

SYNTHETIC = SHARED_DIR / "data" / "synthetic"


def write_predictions(views, dest: Path) -> Path:
    """YOLO predictions (class 0, conf 0.9) of each reference view's own box, named by its file stem."""
    dest.mkdir(parents=True, exist_ok=True)
    for v in views:
        x1, y1, x2, y2 = v.box
        (dest / f"{v.stem}.txt").write_text(
            f"0 {(x1 + x2) / 2 / v.width:.8f} {(y1 + y2) / 2 / v.height:.8f} {(x2 - x1) / v.width:.8f} "
            f"{(y2 - y1) / v.height:.8f} 0.9\n")
    return dest


def write_truth_cameras(dest: Path, shift_m: float = 0.0) -> Path:
    """The truth's cameras of both sets as a cameras tree, each centre moved ``shift_m`` along x."""
    def put(league: str, season: str, match: str, image: str, cam: dict) -> None:
        cam = {**cam, "position_meters": [cam["position_meters"][0] + shift_m, *cam["position_meters"][1:]]}
        path = dest / camera_file(league, season, match, image)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(cam))

    for g in json.loads((SYNTHETIC / "soccernet-v3-dev.truth.json").read_text())["games"]:
        for s in g["systems"]:
            for v in s["views"]:
                put(g["league"], g["season"], g["match"], v["image"], v["camera"])
    for cam_id, cam in json.loads((SYNTHETIC / "issia-dev.truth.json").read_text())["cameras"].items():
        put(LEAGUE, SEASON, "issia-dev", f"cam{cam_id}", cam)
    return dest


def build(url: str) -> None:
    """Import the SoccerNet-v3 dev set and the ISSIA dev sequence into ``url``."""
    from app.services.issia.sequences import import_issia
    from app.services.transfer.importing import import_soccernet_v3

    upgrade_database(url)
    engine = make_engine(url)
    settings = Settings(database_url=url, calibration_workers=0)
    with make_session_factory(engine)() as session:
        import_soccernet_v3(session, SYNTHETIC / "soccernet-v3-dev", settings)
        session.commit()
        import_issia(session, SYNTHETIC / "issia-dev", settings)
        session.commit()
    engine.dispose()


def rows(url: str, work: Path) -> dict:
    """``{set: {row: report}}`` for the sets "soccernet-v3 dev (all splits)" and "issia dev (test split)"."""
    from app.services.evaluation.monocular import evaluate, with_cameras
    from app.services.transfer.detector_files import load_predictions

    upgrade_database(url)
    engine = make_engine(url)
    out: dict = {}
    with make_session_factory(engine)() as session:
        views = reference_views(session, include_all=True)
        pred = write_predictions(views, work / "predictions")
        sets = {"soccernet-v3 dev (all splits)": lambda v: not v.game_path.startswith(f"{LEAGUE}/"),
                "issia dev (test split: cameras 1-2)":
                    lambda v: v.game_path.startswith(f"{LEAGUE}/") and v.split == "test"}
        for name, cams in (("oracle", None), ("truth cameras", write_truth_cameras(work / "truth")),
                           ("truth cameras, centres 2 m off", write_truth_cameras(work / "shifted", 2.0))):
            given, _ = with_cameras(views, cams) if cams is not None else (views, 0)
            for set_name, keep in sets.items():
                chosen = [v for v in given if keep(v)]
                dets, _ = load_predictions(pred, chosen)
                out.setdefault(set_name, {})[name] = evaluate(chosen, dets)
    engine.dispose()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--database-url")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        url = args.database_url or f"sqlite:///{Path(tmp) / 'table2.sqlite3'}"
        if not args.database_url:
            build(url)
        result = rows(url, Path(tmp))
    for set_name, by_row in result.items():
        print(set_name)
        for name, r in by_row.items():
            print(f"  {name:<32} AP50 {r['AP50']}  MAE {r['MAE_m']:.3f} m  {r['MAE_pct']:.2f} %  P@2m {r['P_2m']:.3f}  "
                  f"views {r['counts']['localised']}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1, default=str) + "\n")


if __name__ == "__main__":
    main()
