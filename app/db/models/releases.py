"""Releases: named, immutable snapshots of the accepted systems (``app.services.releases``), their content stored
as canonical JSON documents once by digest. Append-only: the migration adds triggers refusing UPDATE and DELETE.
"""
from __future__ import annotations

from datetime import datetime
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, validates

from app.core.names import name_key
from app.db.models.base import Base
from app.db.types import decompressed_json, utcnow


class Release(Base):
    """One release: ``name`` (unique), ``note``, who made it and when, the counts ``systems`` (accepted systems
    it holds) and ``views`` (their frames), and ``hash``: the SHA-256 (hex) of its canonical content
    (``app.services.releases.content.release_hash``; the recipe in docs/exports.md)."""

    __tablename__ = "releases"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(sa.String(200), unique=True)
    #: ``app.core.names.name_key`` of the name, set with it: two names people read as one cannot both be stored.
    #: Nullable only because SQLite cannot add a NOT NULL column to a filled table without rebuilding it (and its
    #: append-only triggers); every row the model writes has one.
    name_key: Mapped[Optional[str]] = mapped_column(sa.String(220), unique=True, index=True)
    note: Mapped[str] = mapped_column(sa.Text, default="")
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str] = mapped_column(sa.String(200))
    systems: Mapped[int]
    views: Mapped[int]
    hash: Mapped[str] = mapped_column(sa.String(64))
    #: The settings its exports are rendered with, recorded when it was made (``{"ball_diameter_m",
    #: "export_ball_box"}``: ``app.services.releases.render``); not part of its documents or hash. NULL for the
    #: releases made before they were recorded, which render with their document version's values then.
    export_settings: Mapped[Optional[dict[str, Any]]]

    @validates("name")
    def _keyed(self, _: str, name: str) -> str:
        self.name_key = name_key(name)
        return name


class ReleaseDocument(Base):
    """One document of release content, stored once however many releases name it: ``digest`` is the SHA-256 of
    its canonical JSON (``app.db.types.json_digest``), ``body`` that JSON compressed
    (``app.db.types.compressed_json``)."""

    __tablename__ = "release_documents"

    digest: Mapped[str] = mapped_column(sa.String(64), primary_key=True)
    body: Mapped[bytes] = mapped_column(sa.LargeBinary)

    @property
    def value(self) -> Any:
        """The document (a fresh object at each read)."""
        return decompressed_json(self.body)


class ReleaseGame(Base):
    """A game of a release and its document (folder names, what its labels file carries, as-of time)."""

    __tablename__ = "release_games"

    release_id: Mapped[int] = mapped_column(sa.ForeignKey("releases.id"), primary_key=True)
    game_id: Mapped[int] = mapped_column(primary_key=True)
    digest: Mapped[str] = mapped_column(sa.ForeignKey("release_documents.digest"))


class ReleaseSystem(Base):
    """An accepted system of a release, its name and game (for a diff without reading documents) and its document
    (its frames' labels, lines, calibrations, decisions and its 3D result)."""

    __tablename__ = "release_systems"

    release_id: Mapped[int] = mapped_column(sa.ForeignKey("releases.id"), primary_key=True)
    system_id: Mapped[int] = mapped_column(primary_key=True)
    game_id: Mapped[int]
    name: Mapped[str] = mapped_column(sa.String(400))
    digest: Mapped[str] = mapped_column(sa.ForeignKey("release_documents.digest"))
