"""A released split taken in (``v3d import split FILE --set train|test``).

The file lists images, one ``<league>/<season>/<match>/<image>`` a line (as the released ``SNv3D-train.txt`` and
``SNv3D-test.txt``; blank lines and lines starting with ``#`` are skipped, a trailing ``\\r`` ignored). Every
stored frame a line names (game by league, season and match; frame by its name, with or without its
extension) gets ``frames.split = set``, which the exports and benchmarks then use in place of the kind's own
split (``app.services.kinds.KindPolicy.split``). Lines that name no stored image are reported, not an error;
all frames named are updated in one transaction.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import InvalidInputError
from app.datasets.files import read_text_file
from app.db.models import Frame, Game, System
from app.db.unit import write_unit

SPLIT_SETS = ("train", "test")
#: Size of a split file read at most (a released list of 30,000 images is about 3 MB).
MAX_SPLIT_FILE_BYTES = 64 << 20


@dataclass
class SplitReport:
    """What :func:`import_split` did: lines read, frames set (``changed``: their split was another or none)
    and the lines that name no stored image (in file order, as written)."""

    set: str
    lines: int = 0
    frames: int = 0
    changed: int = 0
    unknown: list[str] = field(default_factory=list)


def read_split_file(path: str | Path) -> list[str]:
    """The image lines of a split file (module docstring), as written (stripped).

    Raises:
        DatasetError: a file that is missing, too large or not UTF-8 text.
    """
    path = Path(path)
    text = read_text_file(path, MAX_SPLIT_FILE_BYTES, "text file")
    return [s for line in text.splitlines() if (s := line.strip()) and not s.startswith("#")]


def import_split(session: Session, path: str | Path, set_name: str) -> SplitReport:
    """Make the images listed in ``path`` the ``set_name`` split ("train" or "test") of the exports and
    benchmarks (module docstring); commits.

    Raises:
        InvalidInputError: ``set_name`` not "train" or "test" (field ``set``).
        DatasetError: the file cannot be read (:func:`read_split_file`).
    """
    if set_name not in SPLIT_SETS:
        raise InvalidInputError(f"must be one of {list(SPLIT_SETS)}, not {set_name!r}", field="set")
    lines = read_split_file(path)
    report = SplitReport(set_name, lines=len(lines))
    wanted: dict[tuple[str, str, str], dict[str, str]] = {}
    for line in lines:
        parts = PurePosixPath(line).parts
        if len(parts) != 4:
            report.unknown.append(line)
            continue
        wanted.setdefault(parts[:3], {})[parts[3]] = line
    found: set[str] = set()
    with write_unit(session, lock=False):
        for (league, season, match), images in wanted.items():
            frames = session.scalars(
                sa.select(Frame).join(System, System.id == Frame.system_id).join(Game, Game.id == System.game_id)
                .where(Game.league == league, Game.season == season, Game.match == match)
            ).all()
            for frame in frames:
                listed = images.get(frame.name) or images.get(PurePosixPath(frame.name).stem)
                if listed is None:
                    continue
                found.add(listed)
                report.frames += 1
                if frame.split != set_name:
                    frame.split = set_name
                    report.changed += 1
    report.unknown.extend(line for images in wanted.values() for line in images.values() if line not in found)
    return report
