"""What an import reads within: the caps of ``settings`` on an imported game (views a system, player boxes a frame)
and the limits a reader reads an image within (pixels, bytes), so that one file cannot make an import cost more than
its stored rows (:mod:`app.services.transfer.importing`, :mod:`app.services.transfer.import_formats`)."""
from __future__ import annotations

import dataclasses
from collections.abc import Callable

from app.core.config import Settings
from app.datasets.records import GameRecord


def image_bytes(settings: Settings) -> int:
    """``V3D_MAX_IMAGE_MB`` in bytes: the most an imported image file or zip member may have."""
    return int(settings.max_image_mb * (1 << 20))


def reading_limits(settings: Settings) -> dict[str, int]:
    """The limits :func:`app.datasets.soccernet_v3.read_soccernet_v3_game` reads a game within, from ``settings``:
    pixels and bytes an image, player boxes a frame (those beyond are counted, never read)."""
    return {"max_pixels": settings.max_image_pixels, "max_players": settings.max_players_per_frame,
            "max_image_bytes": image_bytes(settings)}


def within_view_cap(rec: GameRecord, settings: Settings, skipped: list[str] | None = None) -> GameRecord:
    """The game ``rec`` without its systems of more than ``settings.max_views_per_system`` views (the
    pairwise work grows with the square of the views), each named with its count in ``skipped`` when given.
    A system stored before the cap is left as it is."""
    cap = settings.max_views_per_system
    kept = [s for s in rec.systems if len(s.frames) <= cap]
    if len(kept) == len(rec.systems):
        return rec
    if skipped is not None:
        skipped += [f"{rec.league}/{rec.season}/{rec.match}/{s.name}: {len(s.frames)} views, more than "
                    f"{cap} (V3D_MAX_VIEWS_PER_SYSTEM); not imported" for s in rec.systems if len(s.frames) > cap]
    return dataclasses.replace(rec, systems=kept)


def within_player_cap(rec: GameRecord, settings: Settings) -> tuple[GameRecord, int]:
    """The game ``rec`` with at most ``settings.max_players_per_frame`` player boxes a frame, the first in the file's
    order (they only help place the cameras the lines cannot; a real frame boxes a few dozen people), and how many
    boxes were left out: those the reader counted without reading them (``FrameRecord.players_dropped``: the
    SoccerNet-v3 reader stops at the cap and keeps no box past it for a release), and those of a reader without the
    cap, dropped here."""
    cap = settings.max_players_per_frame
    counted = sum(f.players_dropped for s in rec.systems for f in s.frames)  # by a reader that stopped at the cap
    if all(len(f.players) <= cap for s in rec.systems for f in s.frames):
        return rec, counted
    dropped = counted + sum(max(0, len(f.players) - cap) for s in rec.systems for f in s.frames)
    systems = [dataclasses.replace(s, frames=[dataclasses.replace(f, players=f.players[:cap])
                                              if len(f.players) > cap else f for f in s.frames])
               for s in rec.systems]
    return dataclasses.replace(rec, systems=systems), dropped


def read_within_caps(read: Callable[[], GameRecord], settings: Settings) -> GameRecord:
    """``read()`` through :func:`within_view_cap` and :func:`within_player_cap` (what a batch stores)."""
    return within_player_cap(within_view_cap(read(), settings), settings)[0]
