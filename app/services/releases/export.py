"""Exports read from a release instead of the live database (``app.services.transfer.export_zip.ExportSource``).

This module reads a release: its documents (``app.services.releases.content``, typed by their version:
``app.services.releases.document``) in a fixed order, the stored frames whose images the exports copy (checked
against what was imported: ``app.services.images.serving``), and the settings it recorded. What a document becomes
in each format is its version's renderer's (``app.services.releases.render.v1``: the rows, the kinds each format
takes, the settings of releases made before they were recorded, and the live writers it renders through), so that a
release's export is the export of the database as it was when the release was made, whatever the live export does
later. Version 2 documents (a system's says how it was accepted) render as version 1 does: the format files
carry nothing of how a system was accepted, the release's documents file does. A later version that changes what
a format writes adds its renderer and the choice of it here, by the documents' type.

:class:`ReleaseSource` yields each game's ``Labels-v3D.json`` and ``SNv3D.csv`` rows; each game's
``GameMetadata.v3d_release`` names the release and its hash; the archive ends with ``v3d-release.json`` (the
release: name, note, created_at, created_by, systems, views, hash, and the digest of every document, the CSV's
companion file) and ``v3d-release/documents.jsonl.gz`` (every document's canonical JSON, one a line, in increasing
digest order, gzip), from which anyone recomputes the hash (docs/exports.md). That file is the stored documents laid
one after another (each a gzip member, a newline member after each): an export copies them, it neither decompresses
nor compresses them, and the zip stores it as it is. The cameras, ISSIA-3D, YOLO and COCO exports read a release too,
with the same two files at their root. Nothing in a release export depends on when it is written or on the
process's settings: the same release exports to the same bytes.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import orjson
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Frame, Release
from app.db.types import compressed_json
from app.services.issia.export import Issia3DExport
from app.services.releases.content import (
    ReleaseContent,
    read_games,
    read_systems,
    release_content,
    release_summary,
    stored_documents,
)
from app.services.releases.document import GameDocument
from app.services.releases.render import v1
from app.services.releases.render.v1 import ReleasedSystem, released_system
from app.services.storage.datasets import DatasetFiles
from app.services.transfer.cameras_export import CamerasExport, CameraView
from app.services.transfer.detector_export import DetectorExportReport
from app.services.transfer.exporting import ExportedGame, safe_component

#: The release's description at the root of its export (the companion file of ``SNv3D.csv``).
RELEASE_FILE = "v3d-release.json"
#: Every document of the release, one canonical JSON a line, in increasing digest order, gzip (multi-member).
DOCUMENTS_FILE = "v3d-release/documents.jsonl.gz"
#: The line end after each document of :data:`DOCUMENTS_FILE`, a gzip member of its own as the documents are.
_LINE_END = compressed_json(b"\n")
#: Games whose documents are read per query.
_BATCH_GAMES = 25
#: Systems whose documents (and stored frames, for their images) are read per query by the detector exports.
_BATCH_SYSTEMS = 200


def release_manifest(release: Release, content: ReleaseContent) -> dict[str, Any]:
    """The release as its exports name it (:data:`RELEASE_FILE`): its summary and the digest of every game and
    system document (``games``: game id -> digest, ``systems``: system id -> digest; ids as text)."""
    return {**release_summary(release),
            "games": {str(gid): d for gid, d in sorted(content.games.items())},
            "systems": {str(sid): d for sid, (_, _, d) in sorted(content.systems.items())}}


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
        games = read_games(self.session, content.games.values())
        per_game: dict[int, list[tuple[int, str]]] = {}
        for sid, (gid, _, digest) in sorted(content.systems.items()):
            per_game.setdefault(gid, []).append((sid, digest))
        order = sorted((games[content.games[gid]] for gid in per_game),
                       key=lambda g: (g.league, g.season, g.match, g.game_id))
        for game in order:
            for what, value in (("league", game.league), ("season", game.season), ("match", game.match)):
                safe_component(value, f"game {game.game_id} {what}")
        return self._games(order, per_game, progress)

    def _games(self, order: list[GameDocument], per_game: dict[int, list[tuple[int, str]]],
               progress: Callable[[str, int, int], None] | None) -> Iterator[ExportedGame]:
        marker = {"name": self.release.name, "hash": self.release.hash}
        done = 0
        for first in range(0, len(order), _BATCH_GAMES):
            batch = order[first:first + _BATCH_GAMES]
            docs = read_systems(self.session, (d for g in batch for _, d in per_game[g.game_id]))
            for game in batch:
                exported = v1.soccernet_game(game, [docs[d] for _, d in per_game[game.game_id]], marker)
                done += 1
                if exported is not None:
                    yield exported
                if progress:
                    progress("export", done, len(order))

    def members(self) -> Iterator[tuple[str, bytes]]:
        """:func:`release_files`."""
        return release_files(self.session, self.release)


def release_files(session: Session, release: Release) -> Iterator[tuple[str, bytes]]:
    """The files naming a release in each of its exports: :data:`RELEASE_FILE` then :data:`DOCUMENTS_FILE`."""
    content = release_content(session, release)
    yield RELEASE_FILE, orjson.dumps(release_manifest(release, content),
                                     option=orjson.OPT_SORT_KEYS | orjson.OPT_INDENT_2)
    digests = [*content.games.values(), *(d for _, _, d in content.systems.values())]
    yield DOCUMENTS_FILE, b"".join(body + _LINE_END for _, body in stored_documents(session, digests))


def _in_game_order(session: Session, content: ReleaseContent) -> tuple[dict[int, GameDocument],
                                                                        list[tuple[int, tuple[int, str, str]]]]:
    """The release's games (game id -> document) and its systems (id, (game id, name, digest)) in (league, season,
    match, system id) order."""
    games = {g.game_id: g for g in read_games(session, content.games.values()).values()}
    order = sorted(content.systems.items(), key=lambda kv: (
        games[kv[1][0]].league, games[kv[1][0]].season, games[kv[1][0]].match, kv[0]))
    return games, order


def release_camera_views(session: Session, release: Release) -> list[CameraView]:
    """The views of the cameras export (``app.services.transfer.cameras_export.camera_views``) read from a release's
    documents: the released systems of the kinds that take the ``cameras`` export, in (league, season, match, system
    id) order, each view with field lines or an admitted camera, named and split as the live export names them."""
    games, order = _in_game_order(session, release_content(session, release))
    docs = read_systems(session, (d for _, (_, _, d) in order))
    return [view for _, (gid, _, digest) in order for view in v1.camera_views(games[gid], docs[digest])]


def release_detector_systems(session: Session, release: Release, export: str) -> Iterator[ReleasedSystem]:
    """The released systems the export ``export`` (``yolo``, ``coco``, ``issia-3d``) writes, as the detector and
    ISSIA-3D exports read stored systems (``render.v1.ReleasedSystem``: game, kind, frame index, frames with their ball
    label, calibration, optimised box, reprojection and release entry, the triangulation with its pairs, the
    trajectory point), in (league, season, match, system id) order. Each frame's image is the stored frame of that
    id (its image as imported), or none when the frame is gone (the view is then counted without image)."""
    kinds = v1.KINDS[export]
    games, order = _in_game_order(session, release_content(session, release))
    for start in range(0, len(order), _BATCH_SYSTEMS):
        batch = order[start:start + _BATCH_SYSTEMS]
        docs = read_systems(session, (d for _, (_, _, d) in batch))
        wanted = [docs[d] for _, (_, _, d) in batch if docs[d].kind in kinds]
        ids = [f.frame_id for s in wanted for f in s.frames]
        stored = {f.id: f for f in session.scalars(select(Frame).where(Frame.id.in_(ids)))} if ids else {}
        for doc in wanted:
            yield released_system(doc, games[doc.game_id], stored)


def export_release_issia3d(session: Session, release: Release, out_dir: Path) -> Issia3DExport:
    """The ISSIA-3D export of a release under ``out_dir`` (``render.v1.issia_3d`` of its ISSIA systems) with the
    files naming the release (:func:`release_files`)."""
    report = v1.issia_3d(out_dir, release_detector_systems(session, release, "issia-3d"))
    write_release_files(session, release, out_dir)
    return report


def export_release_cameras(session: Session, release: Release, out_dir: Path) -> CamerasExport:
    """The cameras export of a release under ``out_dir`` (``render.v1.cameras`` of
    :func:`release_camera_views`) with the files naming the release (:func:`release_files`) at its root."""
    report = v1.cameras(out_dir, release_camera_views(session, release))
    write_release_files(session, release, out_dir)
    return report


def export_release_detector(session: Session, release: Release, fmt: Literal["yolo", "coco"], out_dir: Path,
                            files: DatasetFiles) -> DetectorExportReport:
    """The YOLO or COCO export of a release under ``out_dir`` (``render.v1.detector``), its ball boxes chosen with
    the settings the release recorded (``render.v1.export_settings``), with the files naming the release
    (:func:`release_files`); ``files``: where the stored frames' images are read."""
    marker = {"name": release.name, "hash": release.hash}
    report = v1.detector(session, fmt, out_dir, release_detector_systems(session, release, fmt), marker,
                         v1.export_settings(release), files)
    write_release_files(session, release, out_dir)
    return report


def write_release_files(session: Session, release: Release, out_dir: Path) -> None:
    """:func:`release_files` written under ``out_dir`` (a tree export of the release)."""
    for name, data in release_files(session, release):
        (out_dir / name).parent.mkdir(parents=True, exist_ok=True)
        (out_dir / name).write_bytes(data)
