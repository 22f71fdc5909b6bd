"""A flood of a detector's predictions (``V3D_MAX_PREDICTIONS_PER_FRAME``): an import keeps each frame's best by score
in the room the other sources leave and counts the rest; it checks its whole file before writing and then writes in
short transactions another writer gets in between; every read takes at most the cap per frame, also from a database
written before the cap; the YOLO and COCO readers keep each image's best while reading."""
from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pytest
import sqlalchemy as sa

from app.core.config import Settings
from app.core.errors import DatasetError
from app.db.models import AuditEntry, Frame, Game, Prediction
from app.geometry.metrics import BestDetections
from app.services.audit.log import entry_summary
from app.services.derivation.doubts import stored_detections
from app.services.derivation.recompute import load_for_recompute
from app.services.evaluation.monocular import source_detections
from app.services.transfer import predictions as module
from app.services.transfer.detector_files import load_predictions
from app.services.transfer.predictions import import_predictions

pytestmark = pytest.mark.engine

HEADER = "league,season,match,image,x1,y1,x2,y2,score\n"


def _frames(session) -> list[tuple[Game, Frame]]:
    return list(session.execute(sa.select(Game, Frame).join(Frame.system).join(Game).order_by(Frame.id)).all())  # type: ignore[arg-type]  # rows unpack as (game, frame)


def _row(game: Game, image: str, score: float, x: float = 100.0) -> str:
    return f"{game.league},{game.season},{game.match},{image},{x},100,{x + 20},120,{score}\n"


def _scores(session, frame_id: int, source: str | None = None) -> list[float]:
    q = sa.select(Prediction.score).where(Prediction.frame_id == frame_id).order_by(Prediction.score.desc())
    return list(session.scalars(q if source is None else q.where(Prediction.source == source)))


def _capped(settings: Settings, cap: int) -> Settings:
    return settings.model_copy(update={"max_predictions_per_frame": cap})


def test_an_import_keeps_each_frames_best_in_the_room_the_others_leave_and_counts_the_rest(
        db_session, settings, imported, tmp_path: Path) -> None:
    (game, f0), (_, f1) = _frames(db_session)[:2]
    capped = _capped(settings, 4)
    other = tmp_path / "other.csv"
    other.write_text(HEADER + _row(game, f0.name, 0.99) + _row(game, f0.name, 0.2))
    assert import_predictions(db_session, other, capped).stored == 2
    flood = tmp_path / "flood.csv"
    n = 3000
    with flood.open("w") as out:
        out.write(HEADER)
        for i in range(n):  # scores rise and fall, the best are spread through the file
            out.write(_row(game, f0.name, round(((i * 7919) % n) / n, 6), x=float(i % 500)))
        for i in range(5):
            out.write(_row(game, f1.name, 0.1 * (i + 1)))
    report = import_predictions(db_session, flood, capped)
    # f0: two of the four places are the other source's, so the flood keeps its two best there; f1 its four best
    assert (report.rows, report.stored, report.dropped, report.cap) == (n + 5, 6, n + 5 - 6, 4)
    assert _scores(db_session, f0.id, "flood") == [round((n - 1) / n, 6), round((n - 2) / n, 6)]
    assert _scores(db_session, f0.id, "other") == [0.99, 0.2]  # an import never removes another source's
    assert _scores(db_session, f1.id) == [0.5, 0.4, pytest.approx(0.3), 0.2]
    # the report in words: the audit entry says what was kept and what was dropped beyond the cap
    entry = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.action == "import")
                               .order_by(AuditEntry.id.desc())).first()
    assert entry.after["dropped"] == n - 1 and entry.after["cap"] == 4
    words = entry_summary(entry, None)
    assert f"6 stored, {n - 1:,} beyond the cap of 4 a frame" in words and "flood" in words
    # importing the source again replaces its rows, frame by frame, and the room is counted again
    again = tmp_path / "flood2.csv"
    again.write_text(HEADER + _row(game, f1.name, 0.7))
    report = import_predictions(db_session, again, capped, source="flood")
    assert (report.stored, report.replaced, report.dropped) == (1, 6, 0)
    assert _scores(db_session, f0.id) == [0.99, 0.2] and _scores(db_session, f1.id) == [0.7]


def test_a_bad_row_after_a_flood_stores_nothing(db_session, settings, imported, tmp_path: Path) -> None:
    game, f0 = _frames(db_session)[0]
    path = tmp_path / "bad.csv"
    path.write_text(HEADER + "".join(_row(game, f0.name, 0.5) for _ in range(2000))
                    + _row(game, f0.name, 1.5))
    with pytest.raises(DatasetError, match="line 2002 score: 1.5 is not in"):
        import_predictions(db_session, path, _capped(settings, 3))
    assert db_session.scalar(sa.select(sa.func.count(Prediction.id))) == 0


def test_every_read_takes_at_most_the_cap_per_frame_from_a_database_written_before(
        db_session, settings, imported) -> None:
    """Rows written before the cap existed (500 on one frame): the recomputation's load, the doubts and the
    monocular benchmark's read of a source each see the frame's best four."""
    (_, f0), (_, f1) = _frames(db_session)[:2]
    db_session.execute(sa.insert(Prediction), [
        {"source": "old", "frame_id": f0.id, "score": i / 500, "x1": 10.0, "y1": 10.0, "x2": 30.0, "y2": 30.0}
        for i in range(500)] + [{"source": "old", "frame_id": f1.id, "score": 0.5, "x1": 1.0, "y1": 1.0, "x2": 9.0,
                                 "y2": 9.0}])
    db_session.commit()
    sid = f0.system_id
    db_session.expunge_all()
    system = load_for_recompute(db_session, [sid], predictions=4)[sid]
    by_id = {f.id: f for f in system.frames}
    assert sorted((p.score for p in by_id[f0.id].predictions), reverse=True) == [0.998, 0.996, 0.994, 0.992]
    assert [d.score for d in stored_detections(system, 4)[f0.id]] == [0.998, 0.996, 0.994, 0.992]
    db_session.expunge_all()
    bare = db_session.get(Frame, f0.id).system  # loaded without its predictions: the doubts read them capped
    assert len(stored_detections(bare, 3)[f0.id]) == 3

    class View:  # a reference view as the benchmark reads it: its frame id and stem
        def __init__(self, frame_id: int, stem: str) -> None:
            self.frame_id, self.stem = frame_id, stem

    dets, ignored = source_detections(db_session, "old", [View(f0.id, "a"), View(f1.id, "b")], 4)  # type: ignore[list-item]  # what it reads of a view
    assert (list(dets.image_ids), ignored) == (["a"] * 4 + ["b"], 0)
    assert sorted(dets.scores[:4].tolist(), reverse=True) == [0.998, 0.996, 0.994, 0.992]


def test_the_import_writes_in_short_transactions_another_writer_gets_in_between(
        fresh_session_factory, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """On a SQLite file: each time the import reports progress, another connection takes the write lock, writes and
    commits (waiting at most 0.2 s): the import reads its file without the lock and holds it one batch at a time (the
    frames of a batch: one here, so three batches and a summary: four commits of the import)."""
    from tests.api.factories import make_game, make_system

    session = fresh_session_factory("flood")
    url = session.get_bind().url
    settings = Settings(_env_file=None, database_url=str(url), calibration_workers=1, max_predictions_per_frame=2)
    game = make_game(session)
    scene = make_system(session, settings, game, "1.png")
    names = [session.get(Frame, fid).name for fid in scene.frame_ids]
    path = tmp_path / "flood.csv"
    with path.open("w") as out:
        out.write(HEADER)
        for i in range(6000):
            out.write(_row(game, names[i % 3], round(i / 6000, 6)))
    monkeypatch.setattr(module, "BATCH_FRAMES", 1)
    other = sqlite3.connect(url.database, timeout=0.2, isolation_level=None)
    writes: list[str] = []

    def meanwhile(stage: str, done: int, total: int) -> None:
        other.execute("BEGIN IMMEDIATE")  # 'database is locked' after 0.2 s if the import held the lock here
        other.execute("UPDATE games SET as_of = as_of")
        other.execute("COMMIT")
        writes.append(stage)

    commits: list[int] = []
    sa.event.listen(session.get_bind(), "commit", lambda conn: commits.append(1))
    try:
        report = import_predictions(session, path, settings, source="flood", progress=meanwhile)
    finally:
        other.close()
    assert (report.stored, report.dropped, report.batches) == (6, 6000 - 6, 3)
    assert writes.count("predictions") >= 2 and writes.count("store") == 3  # while reading and between batches
    assert len(commits) >= 4  # three batches and the audit entry (then the recomputation's own)


def test_the_yolo_and_coco_readers_keep_each_images_best_while_reading(tmp_path: Path) -> None:
    class View:
        stem, width, height = "v1", 1000, 500

    coco = tmp_path / "results.json"
    entries = [{"image_id": "v1", "category_id": 1, "bbox": [10, 10, 5, 5], "score": (i % 997) / 997}
               for i in range(20_000)]
    coco.write_text(json.dumps(entries))
    from app.services.transfer.detector_export import coco_image_id

    for e in entries:
        e["image_id"] = coco_image_id("v1")
    coco.write_text(json.dumps(entries))
    keep = BestDetections(16)
    dets, ignored = load_predictions(coco, [View()], keep=keep)
    assert (len(dets.scores), keep.dropped, ignored) == (16, 20_000 - 16, 0)
    assert dets.scores.tolist() == sorted(dets.scores.tolist(), reverse=True) and dets.scores[0] == 996 / 997
    # YOLO: two files of one image's stem in two folders, the bound holds across them
    for folder, conf in (("a", 0.3), ("b", 0.6)):
        (tmp_path / "yolo" / folder).mkdir(parents=True)
        (tmp_path / "yolo" / folder / "v1.txt").write_text("".join(f"0 0.5 0.5 0.1 0.1 {conf}\n" for _ in range(40)))
    keep = BestDetections(5)
    dets, _ = load_predictions(tmp_path / "yolo", [View()], keep=keep)
    assert dets.scores.tolist() == [0.6] * 5 and keep.dropped == 75
