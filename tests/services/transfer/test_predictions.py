"""Importing a ball detector's predictions (``app.services.transfer.predictions``): stored by source, replaced on
re-import, unknown images counted and named, boxes clipped, and every malformed file refused naming its line with
nothing stored."""
from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa

from app.core.errors import DatasetError, InvalidInputError
from app.db.models import Frame, Game, Prediction
from app.services.transfer.predictions import (
    PREDICTION_FORMATS,
    import_predictions,
    prediction_input,
    prediction_sources,
    remove_predictions,
)

pytestmark = pytest.mark.engine

HEADER = "league,season,match,image,x1,y1,x2,y2,score\n"


def _frames(session) -> list[tuple[Game, Frame]]:
    return list(session.execute(sa.select(Game, Frame).join(Frame.system).join(Game).order_by(Frame.id)).all())  # type: ignore[arg-type]  # rows unpack as (game, frame)


def _row(game: Game, image: str, box, score=0.9) -> str:
    return f"{game.league},{game.season},{game.match},{image},{box[0]},{box[1]},{box[2]},{box[3]},{score}\n"


def _count(session, source=None) -> int:
    q = sa.select(sa.func.count(Prediction.id))
    if source is not None:
        q = q.where(Prediction.source == source)
    return int(session.scalar(q))


def _write(path: Path, rows: list[str], header: str = HEADER) -> Path:
    path.write_text(header + "".join(rows))
    return path


def test_import_stores_clips_names_unknown_and_replaces(db_session, settings, imported, tmp_path):
    (game, f0), (_, f1) = _frames(db_session)[:2]
    rows = [_row(game, f0.name, (100, 100, 120, 120), 0.91),
            _row(game, f1.name, (-6, 10, 14, 30), 0.5),  # crosses the left edge: clipped to x1 = 0
            _row(game, "no_such.png", (1, 1, 5, 5)),
            _row(game, "no_such.png", (2, 2, 6, 6)),
            "other,2000,nowhere,1.png,1,1,5,5,0.3\n"]
    report = import_predictions(db_session, _write(tmp_path / "yolo-sn-ball.csv", rows), settings)
    assert (report.source, report.rows, report.stored, report.clipped, report.unknown) == ("yolo-sn-ball", 5, 2, 1, 3)
    assert report.unknown_images == [f"{game.league}/{game.season}/{game.match}/no_such.png",
                                     "other/2000/nowhere/1.png"]
    stored = {p.frame_id: p for p in db_session.scalars(sa.select(Prediction))}
    assert (stored[f0.id].x1, stored[f0.id].y2, stored[f0.id].score) == (100.0, 120.0, 0.91)
    assert (stored[f1.id].x1, stored[f1.id].x2) == (0.0, 14.0)
    # the same source again replaces it as a whole; another source is kept beside it
    again = import_predictions(db_session, _write(tmp_path / "b.csv", rows[:1]), settings, source="yolo-sn-ball")
    assert (again.replaced, again.stored) == (2, 1) and _count(db_session, "yolo-sn-ball") == 1
    import_predictions(db_session, _write(tmp_path / "c.csv", rows[:2]), settings, source="other-detector")
    assert [(s["source"], s["predictions"]) for s in prediction_sources(db_session)] == [
        ("other-detector", 2), ("yolo-sn-ball", 1)]
    assert remove_predictions(db_session, settings, "other-detector") == 2
    assert _count(db_session) == 1 and remove_predictions(db_session, settings, "other-detector") == 0


@pytest.mark.parametrize("bad, field", [
    (None, "line 1"),  # wrong columns (header)
    ("{m},0.png,1,1,5\n", "line 3"),  # a row with too few cells
    ("{m},0.png,nan,1,5,5,0.9\n", "line 3 x1..score"),
    ("{m},0.png,1,1,5,inf,0.9\n", "line 3 x1..score"),
    ("{m},0.png,1,1,five,5,0.9\n", "line 3 x1..score"),
    ("{m},0.png,5,1,1,5,0.9\n", "line 3 x1..y2"),  # no area
    ("{m},0.png,1,1,5,5,1.5\n", "line 3 score"),
    ("{m},0.png,5000,10,5020,30,0.9\n", "line 3 x1..y2"),  # entirely outside the image
])
def test_a_malformed_file_names_its_line_and_stores_nothing(db_session, settings, imported, tmp_path, bad, field):
    game, f0 = _frames(db_session)[0]
    import_predictions(db_session, _write(tmp_path / "kept.csv", [_row(game, f0.name, (10, 10, 20, 20))]), settings,
                       source="det")
    m = f"{game.league},{game.season},{game.match}"
    good = _row(game, f0.name, (100, 100, 120, 120))
    if bad is None:
        path = _write(tmp_path / "det.csv", [good], header="league,season,match,image,x,y,w,h,conf\n")
    else:
        path = _write(tmp_path / "det.csv", [good, bad.replace("{m}", m).replace("0.png", f0.name)])
    with pytest.raises(DatasetError) as err:
        import_predictions(db_session, path, settings, source="det")
    assert str(err.value).startswith(f"{path}: {field}"), str(err.value)
    # nothing of the file is stored, and the source's earlier predictions are kept
    assert _count(db_session, "det") == 1
    assert db_session.scalar(sa.select(Prediction.x1).where(Prediction.source == "det")) == 10.0


def test_a_large_file_streams_and_a_bad_last_line_stores_nothing(db_session, settings, imported, tmp_path):
    """Many megabytes of rows (half on stored frames), the last one broken: refused naming that line, nothing
    stored (the whole file is checked before anything is written)."""
    game, f0 = _frames(db_session)[0]
    good = _row(game, f0.name, (100, 100, 120, 120))
    unknown = _row(game, "x.png", (1, 1, 5, 5))
    n = 60_000
    path = tmp_path / "big.csv"
    with path.open("w") as out:
        out.write(HEADER)
        for i in range(n):
            out.write(good if i % 2 else unknown)
        out.write(f"{game.league},{game.season},{game.match},{f0.name},1,1,5,nan,0.9\n")
    assert path.stat().st_size > 5 << 20
    with pytest.raises(DatasetError, match=f"line {n + 2} x1..score: NaN"):
        import_predictions(db_session, path, settings, source="big")
    assert _count(db_session) == 0


def test_a_bad_source_name_is_refused(db_session, settings, imported, tmp_path):
    with pytest.raises(InvalidInputError, match="source must be"):
        import_predictions(db_session, _write(tmp_path / "a.csv", []), settings, source="../x")


def test_an_input_is_the_first_registered_format_it_holds(tmp_path) -> None:
    """The prediction formats' one list (``PREDICTION_FORMATS``) decides what an input holds: a folder's one CSV
    before anything else, then its one COCO results JSON, then its YOLO files; a single file by its extension."""
    assert list(PREDICTION_FORMATS) == ["csv", "coco", "yolo"]
    mixed = tmp_path / "mixed"
    (mixed / "labels").mkdir(parents=True)
    for name in ("rows.csv", "a.json", "b.json", "labels/12_1.txt"):
        (mixed / name).write_text("")
    assert prediction_input(mixed) == ("csv", mixed / "rows.csv")
    (mixed / "rows.csv").unlink()
    with pytest.raises(DatasetError, match="found 0 .csv and 2 .json"):
        prediction_input(mixed)
    (mixed / "b.json").unlink()
    assert prediction_input(mixed) == ("coco", mixed / "a.json")
    (mixed / "a.json").unlink()
    assert prediction_input(mixed) == ("yolo", mixed)
    (mixed / "labels" / "12_1.txt").unlink()
    with pytest.raises(DatasetError, match="found 0 .csv and 0 .json"):
        prediction_input(mixed)
    for name, kind in (("r.JSON", "coco"), ("r.csv", "csv"), ("r.txt", "csv")):
        (tmp_path / name).write_text("")
        assert prediction_input(tmp_path / name) == (kind, tmp_path / name)
