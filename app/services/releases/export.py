"""Exports read from a release instead of the live database (``app.services.transfer.export_zip.ExportSource``).

:class:`ReleaseSource` rebuilds each game's ``Labels-v3D.json`` and ``SNv3D.csv`` rows from the release's documents
(``app.services.releases.content``) with the live export's own functions (``exporting.exported_game``), so a
release's export is the export of the database as it was when the release was made; the images are the frames'
stored images (checked against what was imported: ``app.services.images.serving``). Each game's
``GameMetadata.v3d_release`` names the release and its hash; the archive ends with ``v3d-release.json`` (the
release: name, note, created_at, created_by, systems, views, hash, and the digest of every document, the CSV's
companion file) and ``v3d-release/documents.jsonl`` (every document's canonical JSON, one a line, in increasing
digest order), from which anyone recomputes the hash (docs/exports.md).

Nothing in a release export depends on when it is written: the same release exports to the same bytes.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import orjson
from sqlalchemy.orm import Session

from app.db.models import CalibrationSource, CalibrationStatus, FrameRole, Release, ReviewStatus
from app.services.kinds import kinds_exported_by
from app.services.releases.content import (
    ReleaseContent,
    canonical_documents,
    read_documents,
    release_content,
    release_summary,
)
from app.services.transfer.exporting import ExportedGame, exported_game, safe_component

#: The release's description at the root of its export (the companion file of ``SNv3D.csv``).
RELEASE_FILE = "v3d-release.json"
#: Every document of the release, one canonical JSON a line, in increasing digest order.
DOCUMENTS_FILE = "v3d-release/documents.jsonl"
#: Games whose documents are read per query.
_BATCH_GAMES = 25


def release_manifest(release: Release, content: ReleaseContent) -> dict[str, Any]:
    """The release as its exports name it (:data:`RELEASE_FILE`): its summary and the digest of every game and
    system document (``games``: game id -> digest, ``systems``: system id -> digest; ids as text)."""
    return {**release_summary(release),
            "games": {str(gid): d for gid, d in sorted(content.games.items())},
            "systems": {str(sid): d for sid, (_, _, d) in sorted(content.systems.items())}}


def _enum(cls: Any, value: Any) -> Any:
    return None if value is None else cls(value)


def _row(system: dict[str, Any], frame: dict[str, Any]) -> SimpleNamespace:
    """An export row (as ``exporting.frame_row_select`` reads it) from a system document and one of its frames."""
    row = SimpleNamespace(**frame)
    row.game_id, row.system_id, row.system_name = system["game_id"], system["system_id"], system["name"]
    row.ball3d, row.review_status = system["ball3d"], _enum(ReviewStatus, system["review_status"])
    row.role = FrameRole(frame["role"])
    row.cal_source = _enum(CalibrationSource, frame["cal_source"])
    row.cal_status = _enum(CalibrationStatus, frame["cal_status"])
    return row


@dataclass
class ReleaseSource:
    """A release as the source of a SoccerNet-v3D export (``export_zip.ExportSource``)."""

    session: Session
    release: Release

    def games(self, progress: Callable[[str, int, int], None] | None) -> Iterator[ExportedGame]:
        """The release's games holding SoccerNet-v3 systems, in (league, season, match, id) order, each game's
        systems in id order; every folder name checked before the first game.

        Raises:
            InvalidInputError: a league, season or match that cannot be a folder name.
        """
        content = release_content(self.session, self.release)
        exported_kinds = {k.value for k in kinds_exported_by("soccernet-v3d")}
        games = read_documents(self.session, content.games.values())
        per_game: dict[int, list[tuple[int, str]]] = {}
        for sid, (gid, _, digest) in sorted(content.systems.items()):
            per_game.setdefault(gid, []).append((sid, digest))
        order = sorted((games[content.games[gid]] for gid in per_game),
                       key=lambda g: (g["league"], g["season"], g["match"], g["game_id"]))
        for game in order:
            for what in ("league", "season", "match"):
                safe_component(game[what], f"game {game['game_id']} {what}")
        return self._games(order, per_game, exported_kinds, progress)

    def _games(self, order: list[dict[str, Any]], per_game: dict[int, list[tuple[int, str]]],
               exported_kinds: set[str], progress: Callable[[str, int, int], None] | None) -> Iterator[ExportedGame]:
        marker = {"name": self.release.name, "hash": self.release.hash}
        done = 0
        for first in range(0, len(order), _BATCH_GAMES):
            batch = order[first:first + _BATCH_GAMES]
            docs = read_documents(self.session, (d for g in batch for _, d in per_game[g["game_id"]]))
            for game in batch:
                systems = [docs[d] for _, d in per_game[game["game_id"]]]
                rows = [_row(s, f) for s in systems if s["kind"] in exported_kinds for f in s["frames"]]
                done += 1
                if rows:
                    exported = exported_game(SimpleNamespace(**game), rows, game["as_of"])
                    exported.doc["GameMetadata"]["v3d_release"] = marker
                    yield exported
                if progress:
                    progress("export", done, len(order))

    def members(self) -> Iterator[tuple[str, bytes]]:
        """:data:`RELEASE_FILE` then :data:`DOCUMENTS_FILE`."""
        content = release_content(self.session, self.release)
        yield RELEASE_FILE, orjson.dumps(release_manifest(self.release, content),
                                         option=orjson.OPT_SORT_KEYS | orjson.OPT_INDENT_2)
        digests = [*content.games.values(), *(d for _, _, d in content.systems.values())]
        yield DOCUMENTS_FILE, b"".join(body + b"\n" for _, body in canonical_documents(self.session, digests))
