"""Write the golden files of the current release document version: a release of synthetic data as stored, and the
exact bytes of its export in every format (``tests/services/releases/test_golden.py`` reads them).

Run once per document version, when the version is introduced (it refuses to write over a version's folder: the
golden files of a version are never written again, they are what releases of that version export)::

    PYTHONPATH=. .venv/bin/python -m tests.services.releases.make_golden

The data: two SoccerNet-v3 systems of the test factories (``tests.api.factories``: exact cameras, field lines, ball
boxes; the first view's image a member of the game's ``Frames-v3.zip``, the second a PNG file; one view's box 3 px
off; since version 2 the second is accepted in a batch after a sample, with a vouched system of a second game its
sample, which a person accepts), a third left pending (not released), and a synthetic ISSIA sequence of six static
cameras and five frames (a ball rolling across the centre circle, two views unlabelled), four frames accepted. No data
of ``../shared``.

Written under ``golden/v<DOCUMENT_VERSION>/``: ``release.json`` (the release's row and what it names),
``documents/<digest>.json.gz`` (each document's stored body, as the database holds it), ``frames.json`` and
``images/`` (the stored frames whose images the exports copy), and ``exports/<format>.zip`` (each export of the
release, as ``v3d export <format> --release`` writes it).
"""
from __future__ import annotations

import csv
import json
import random
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Frame, Release, ReleaseDocument, ReleaseGame, ReleaseSystem, ReviewStatus, System
from app.db.models.enums import BallEvidence
from app.db.session import make_engine, upgrade_database
from app.geometry.camera import Camera
from app.services.curation import batches
from app.services.curation.decisions import decide_review
from app.services.curation.queue import SystemFilters
from app.services.exports.files import write_export_zip
from app.services.exports.formats import RELEASE_EXPORTS
from app.services.issia.sequences import import_issia
from app.services.releases.content import create_release
from app.services.releases.document import DOCUMENT_VERSION
from tests.api.factories import make_game, make_system

HERE = Path(__file__).resolve().parent
RELEASE_NAME = "golden"
#: The ISSIA cameras' centres (world metres, SoccerNet frame, z down): three on each long side, 1-2 the test set.
ISSIA_CENTRES = ([-30.0, 50.0, -14.0], [30.0, 50.0, -14.0], [-45.0, -48.0, -16.0], [0.0, -52.0, -18.0],
                 [45.0, -48.0, -16.0], [0.0, 55.0, -20.0])
ISSIA_SIZE = (1920, 1080)


def _issia_camera(centre: list[float], target: np.ndarray) -> Camera:
    """An undistorted ISSIA-size camera at ``centre`` whose optical axis passes through ``target``, no roll."""
    c = np.asarray(centre, float)
    z = target - c
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    K = np.array([[1800.0, 0.0, ISSIA_SIZE[0] / 2], [0.0, 1800.0, ISSIA_SIZE[1] / 2], [0.0, 0.0, 1.0]])
    return Camera(K=K, R=np.stack([x, np.cross(z, x), z]), C=c)


def write_issia(folder: Path) -> Path:
    """A synthetic ISSIA folder: ``issia_calibration.json`` (six cameras) and ``ball_points.csv`` (five frames of a
    ball rolling 0.5 m a frame along x, exact projections rounded to 0.01 px; camera 2 misses frame 1, camera 5
    frame 3)."""
    folder.mkdir(parents=True)
    cameras = {str(k + 1): _issia_camera(c, np.array([0.0, 0.0, 0.0])) for k, c in enumerate(ISSIA_CENTRES)}
    (folder / "issia_calibration.json").write_text(json.dumps({k: c.to_soccernet() for k, c in cameras.items()}))
    missing = {(1, "2"), (3, "5")}
    with (folder / "ball_points.csv").open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["frame", *(f"{a}_cam{k}" for k in cameras for a in "xy")])
        for i in range(5):
            ball = np.array([[-1.0 + 0.5 * i, 2.0, -0.11]])
            cells: list[str] = []
            for k, cam in cameras.items():
                uv = cam.project(ball)[0][0]
                cells += ["", ""] if (i, k) in missing else [f"{uv[0]:.2f}", f"{uv[1]:.2f}"]
            writer.writerow([i, *cells])
    return folder


def _accept_in_a_batch(session: Session, system_id: int) -> None:
    """Accept ``system_id`` in a batch after a sample (version 2 documents say so): a batch of it and a vouched
    system of another game, sampling one of the two at 50 % / 50 %, whose sampled system a person accepts."""
    other = make_system(session, Settings(database_url=str(session.get_bind().url), calibration_workers=1),
                        make_game(session, match="2016-01-01 - 12-00 Sampled 0 - 0 Batch"), "1.png")
    for sid in (system_id, other.system_id):
        system = session.get(System, sid)
        assert system is not None
        system.ball_evidence = BallEvidence.VOUCHED
    session.commit()
    batch = batches.create_batch(session, "golden", SystemFilters(), 0.5, 0.5, rng=random.Random(0))
    sampled = other.system_id
    if batch.sample_ids != [sampled]:  # the seed's draw: keep the golden system out of the sample
        raise RuntimeError(f"the sample is {batch.sample_ids}, not [{sampled}]: choose another seed")
    decide_review(session, system_id=sampled, status=ReviewStatus.ACCEPTED, actor="golden")
    assert batches.accept_batch(session, batch.id, "golden") == 1


def make(out: Path, work: Path) -> None:
    """The golden files (module docstring) of a release made in a fresh SQLite database under ``work``."""
    url = f"sqlite:///{work / 'v3d.sqlite3'}"
    upgrade_database(url)
    settings = Settings(database_url=url, calibration_workers=1)
    images = work / "images"
    images.mkdir()
    with Session(make_engine(url)) as session:
        game = make_game(session)
        scenes = [make_system(session, settings, game, "1.png", image_dir=images),
                  make_system(session, settings, game, "2.png", image_dir=images, shift_px=(0.0, 3.0, 0.0)),
                  make_system(session, settings, game, "3.png")]
        import_issia(session, write_issia(work / "issia-golden"), settings)
        issia = session.scalars(select(System).where(System.frame_index.is_not(None))
                                .order_by(System.frame_index)).all()
        for sid in [scenes[0].system_id, *(s.id for s in issia[:4])]:
            decide_review(session, system_id=sid, status=ReviewStatus.ACCEPTED)
        _accept_in_a_batch(session, scenes[1].system_id)
        session.commit()
        release = create_release(session, RELEASE_NAME, "the golden files' release", actor="golden")
        (out / "documents").mkdir(parents=True)
        for digest, body in session.execute(select(ReleaseDocument.digest, ReleaseDocument.body)):
            (out / "documents" / f"{digest}.json.gz").write_bytes(body)
        stored = {
            "document_version": DOCUMENT_VERSION,
            "release": {"name": release.name, "note": release.note, "created_at": release.created_at.isoformat(),
                        "created_by": release.created_by, "systems": release.systems, "views": release.views,
                        "hash": release.hash},
            "games": {str(g): d for g, d in session.execute(select(ReleaseGame.game_id, ReleaseGame.digest)
                                                            .where(ReleaseGame.release_id == release.id))},
            "systems": {str(s): [g, n, d] for s, g, n, d in session.execute(
                select(ReleaseSystem.system_id, ReleaseSystem.game_id, ReleaseSystem.name, ReleaseSystem.digest)
                .where(ReleaseSystem.release_id == release.id))},
        }
        (out / "release.json").write_text(json.dumps(stored, indent=1, sort_keys=True) + "\n")
        frames = []
        for f in session.scalars(select(Frame).where(Frame.image_root.is_not(None)).order_by(Frame.id)):
            if f.image_zip is None and f.image_path is None:
                continue
            frames.append({"id": f.id, "system_id": f.system_id, "game_id": f.system.game_id, "name": f.name,
                           "width": f.width, "height": f.height, "image_zip": f.image_zip,
                           "image_member": f.image_member, "image_path": f.image_path, "image_type": f.image_type})
            for name in (f.image_zip, f.image_path):
                if name is not None:
                    (out / "images" / name).parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(Path(f.image_root) / name, out / "images" / name)
        (out / "frames.json").write_text(json.dumps(frames, indent=1, sort_keys=True) + "\n")
        assert session.scalar(select(Release.id).where(Release.name == RELEASE_NAME)) == release.id
        (out / "exports").mkdir()
        for fmt in RELEASE_EXPORTS:
            write_export_zip(session, fmt, out / "exports" / f"{fmt}.zip", False, settings, release=RELEASE_NAME)


def main() -> int:
    out = HERE / "golden" / f"v{DOCUMENT_VERSION}"
    if out.exists():
        print(f"{out} exists: the golden files of a document version are written once", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as work:
        try:
            make(out, Path(work))
        except BaseException:
            shutil.rmtree(out, ignore_errors=True)
            raise
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
