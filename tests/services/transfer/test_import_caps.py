"""Views per system at import are bounded (issue 27, item 4: pairwise work grows with the square of the views):
a system of more than ``V3D_MAX_VIEWS_PER_SYSTEM`` views (16) is left out, named in the import's report with
its count, and the rest of the dataset imports; a system stored before the cap is left as it is."""
from __future__ import annotations

import gc
import json
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa

from app.core.errors import DatasetError
from app.datasets.soccernet_v3 import read_soccernet_v3_game
from app.db.models import Frame, PlayerBox, System
from app.services.jobs.work import import_result
from app.services.transfer.importing import import_soccernet_v3
from tests.conftest import sizes

from ..datasets import DEV_GAME, dev_game_dir, write_v3_game

pytestmark = pytest.mark.engine


def _grow(action: str, views: int):
    """An ``edit`` of ``write_v3_game`` giving ``action`` ``views`` views: copies of its first replay."""

    def edit(data: dict) -> None:
        replays = data["actions"][action]["linked_replays"]
        first = replays[0]
        stem = action.split(".")[0]
        for k in range(views - 1 - len(replays)):
            name = f"{stem}_{100 + k}.png"
            data["replays"][name] = json.loads(json.dumps(data["replays"][first]))
            replays.append(name)

    return edit


def _tree(shared_dir: Path, root: Path, views: int) -> Path:
    """The dev game's 0.png and 2.png, 2.png with ``views`` views (images included)."""
    game_dir = write_v3_game(shared_dir, root, actions=("0.png", "2.png"), edit=_grow("2.png", views),
                             with_images=False)
    data = json.loads((game_dir / "Labels-v3.json").read_text())
    src = dev_game_dir(shared_dir) / "Frames-v3.zip"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(game_dir / "Frames-v3.zip", "w") as zout:
        first_replay = data["actions"]["2.png"]["linked_replays"][0]
        for name in [*data["actions"], *data["replays"]]:
            zout.writestr(name, zin.read(name if name in zin.namelist() else first_replay))
    return root


def test_a_system_above_the_view_cap_is_named_in_the_report_and_the_rest_imports(db_session, settings, shared_dir,
                                                                               tmp_path) -> None:
    assert settings.max_views_per_system == 16
    root = _tree(shared_dir, tmp_path / "v3", 17)
    report = import_soccernet_v3(db_session, root, settings)
    game = "/".join(DEV_GAME)
    assert report.skipped_systems == [f"{game}/2.png: 17 views, more than 16 (V3D_MAX_VIEWS_PER_SYSTEM); not imported"]
    assert report.systems == 2  # what the input holds
    names = set(db_session.scalars(sa.select(System.name)))
    assert names == {"0.png"}  # the rest imported
    assert db_session.scalar(sa.select(sa.func.count(Frame.id))) == 2
    assert import_result(report)["skipped_systems"] == report.skipped_systems  # what the job and the CLI show


def test_a_system_at_the_cap_imports_and_one_stored_before_the_cap_is_kept(db_session, settings, shared_dir,
                                                                        tmp_path) -> None:
    root = _tree(shared_dir, tmp_path / "v3", 16)
    report = import_soccernet_v3(db_session, root, settings)
    assert report.skipped_systems == []
    system = db_session.scalars(sa.select(System).where(System.name == "2.png")).one()
    assert len(system.frames) == 16
    # the cap lowered afterwards: the stored system is left as it is, the import names it
    lower = settings.model_copy(update={"max_views_per_system": 8})
    again = import_soccernet_v3(db_session, root, lower)
    assert [s.split(": ")[1] for s in again.skipped_systems] == ["16 views, more than 8 (V3D_MAX_VIEWS_PER_SYSTEM); "
                                                                 "not imported"]
    db_session.expire_all()
    assert len(db_session.scalars(sa.select(System).where(System.name == "2.png")).one().frames) == 16


def _flood(action: str, boxes: int):
    """An ``edit`` of ``write_v3_game`` appending ``boxes`` player boxes to ``action``'s frame (all well formed)."""

    def edit(data: dict) -> None:
        data["actions"][action]["bboxes"] += [
            {"class": "Player team left", "ID": i, "points": {"x1": 10 + i % 900, "y1": 20, "x2": 30 + i % 900,
                                                            "y2": 80}} for i in range(boxes)]

    return edit


@pytest.mark.parametrize("boxes", sizes(2_000, 120_000))
def test_player_boxes_beyond_the_cap_a_frame_are_counted_not_stored(db_session, settings, shared_dir, tmp_path,
                                                                    boxes: int) -> None:
    """A flood of player boxes on one frame (120,000: a 2.9 MB zip) keeps ``V3D_MAX_PLAYERS_PER_FRAME`` of them, the
    first in the file's order; the rest are counted in the report and its words, and neither stored nor kept for a
    release (the frame's entry keeps its ball and the boxes up to the cap); the other frames keep all theirs.
    ``benchmarks/player_flood.py`` times such a flood against the same game without it."""
    cap = settings.max_players_per_frame
    assert cap == 200
    plain = write_v3_game(shared_dir, tmp_path / "plain", with_images=False)
    given = {name: len([b for b in item["bboxes"] if b["class"] != "Ball"])
             for section in ("actions", "replays")
             for name, item in json.loads((plain / "Labels-v3.json").read_text())[section].items()}
    assert 0 < given["0.png"] < cap and max(given.values()) <= cap
    write_v3_game(shared_dir, tmp_path / "flood", edit=_flood("0.png", boxes), with_images=False)
    report = import_soccernet_v3(db_session, tmp_path / "flood", settings)
    assert report.players_dropped == given["0.png"] + boxes - cap
    stored = dict(db_session.execute(sa.select(Frame.name, sa.func.count(PlayerBox.id))
                                     .join(PlayerBox, PlayerBox.frame_id == Frame.id).group_by(Frame.name)).all())
    assert stored == {**given, "0.png": cap}
    first = db_session.scalars(sa.select(PlayerBox.ident).join(Frame, Frame.id == PlayerBox.frame_id)
                               .where(Frame.name == "0.png").order_by(PlayerBox.id)).all()
    assert first[given["0.png"]:] == [str(i) for i in range(cap - given["0.png"])]  # the first, in the file's order
    releases = dict(db_session.execute(sa.select(Frame.name, Frame.release)).all())
    flooded = releases["0.png"]["bboxes"]
    assert [b["class"] for b in flooded].count("Ball") == 1 and len(flooded) == cap + 1  # the ball, then the cap's
    assert [b["ID"] for b in flooded if b["class"] != "Ball"][given["0.png"]:] == list(range(cap - given["0.png"]))
    result = import_result(report)
    assert result["players_dropped"] == report.players_dropped
    assert f"{report.players_dropped:,} player boxes beyond the cap a frame not stored" in result["summary"]["words"]
    again = import_soccernet_v3(db_session, tmp_path / "flood", settings)  # the same file again changes nothing
    assert (again.systems_new, again.systems_changed, again.players_dropped) == (0, 0, report.players_dropped)


def test_reading_a_flooded_labels_file_starts_no_collection(settings, shared_dir, tmp_path) -> None:
    """Reading a labels file of 20,000 boxes starts no garbage collection while the parsed document is held (its
    boxes are dropped before one could traverse them: a parse makes no cycle) and leaves the collector running.
    ``benchmarks/player_flood.py`` times what that saves an import."""
    game_dir = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), edit=_flood("0.png", 20_000),
                             with_images=False)
    gc.collect()  # no young collection falls due for what was made before the reading
    collections: list[int] = []
    gc.callbacks.append(lambda phase, info: collections.append(info["generation"]) if phase == "start" else None)
    try:
        game = read_soccernet_v3_game(game_dir / "Labels-v3.json", max_players=settings.max_players_per_frame)
    finally:
        gc.callbacks.pop()
    assert game.systems[0].frames[0].players_dropped > 0
    # At most the one young collection the kept records fall due for once the document is dropped (before: one per
    # 700 parsed objects, dozens here, and full ones over the whole process).
    assert collections in ([], [0]) and gc.isenabled()


@pytest.mark.parametrize(("damage", "words"), [
    (lambda data: data.update(deep=json.loads("[" * 900 + "]" * 900)), "nested too deep"),
    (lambda data: data["actions"]["0.png"]["imageMetadata"].update(width=123456789), "more than 4300 digits"),
], ids=["deep", "long-number"])
def test_a_label_file_too_deep_or_with_a_number_too_long_is_refused_in_words(db_session, settings, shared_dir,
                                                                             tmp_path, damage, words) -> None:
    game = write_v3_game(shared_dir, tmp_path / "v3", with_images=False)
    labels = game / "Labels-v3.json"
    data = json.loads(labels.read_text())
    damage(data)
    text = json.dumps(data)
    # deeper than any parser's recursion (100,000 arrays), longer than Python reads (5,000 digits)
    text = text.replace("[" * 900 + "]" * 900, "[" * 100_000 + "]" * 100_000).replace("123456789", "7" * 5000)
    labels.write_text(text)
    with pytest.raises(DatasetError) as refused:
        import_soccernet_v3(db_session, tmp_path / "v3", settings)
    assert str(refused.value).startswith(f"{labels}: ") and words in str(refused.value)
    assert db_session.scalar(sa.select(sa.func.count(Frame.id))) == 0
