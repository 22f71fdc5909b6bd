"""Views per system at import are bounded (issue 27, item 4: pairwise work grows with the square of the views):
a system of more than ``V3D_MAX_VIEWS_PER_SYSTEM`` views (16) is left out, named in the import's report with
its count, and the rest of the dataset imports; a system stored before the cap is left as it is."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa

from app.db.models import Frame, System
from app.services.jobs.work import import_result
from app.services.transfer.importing import import_soccernet_v3

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
