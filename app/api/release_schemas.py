"""Pydantic schemas of ``/api/releases`` (``app.api.routes.releases``): a release, the body that makes one, and
the diff of two (``app.services.releases.diff``)."""
from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Annotated, Literal, Optional

from pydantic import BaseModel, Field

from app.api.schemas import _In, readable_name
from app.services.releases import content
from app.services.releases.diff import WHY_REMOVED

if TYPE_CHECKING:  # mypy cannot build a Literal from values computed at import
    WhyRemoved = str
else:
    WhyRemoved = Literal[WHY_REMOVED]

class ReleaseIn(_In):
    name: Annotated[str, readable_name(content.NAME_MAX, "a release name")] = Field(
        min_length=1, max_length=content.NAME_MAX,
        description="Unique, also by its NFKC case-folded form (409); no leading or trailing space, '/', '\\', "
                    "control or format character (Unicode Cc, Cf), not dots alone; stored in NFC.")
    note: str = Field("", max_length=10_000, description="Free text kept with the release.")


class ReleaseOut(BaseModel):
    """A release: the accepted systems as they were when it was made, immutably."""

    name: str
    note: str
    created_at: datetime
    created_by: str = Field(description="Who made it as stored: a user's name, or cli:<os user> for the command "
                                        "line.")
    made_by: str = Field(description="Who made it in words: the user's name, or 'command line' (with the OS account "
                                     "for admins: 'command line (root)').")
    systems: int = Field(description="Accepted systems it holds.")
    without_ball3d: int = Field(description="Of those, the systems accepted with no 3D ball (their views agreed on "
                                            "no ball), counted from the release's documents.")
    views: int = Field(description="Their views (frames).")
    hash: str = Field(description="SHA-256 (hex) of its canonical content (docs/exports.md gives the recipe).")


class ReleasesOut(BaseModel):
    items: list[ReleaseOut]


class DiffEnd(BaseModel):
    name: str
    hash: str


class DiffSystem(BaseModel):
    system_id: int
    name: str
    game: str = Field(description="league/season/match")


class DiffView(BaseModel):
    frame_id: int
    view: str = Field(description="The frame's name.")
    changes: list[Literal["label", "lines", "calibration", "decision", "added", "removed"]]


class DiffRemoved(DiffSystem):
    why: WhyRemoved = Field(description="Why it left: rejected, no longer accepted (pending, needs fix or fixed now) "
                                        "or deleted.")


class DiffChanged(DiffSystem):
    ball3d_moved_m: Optional[float] = Field(description="How far the 3D ball moved (world m); null when either "
                                                        "release's system has none.")
    views: list[DiffView]


class DiffOut(BaseModel):
    from_: DiffEnd = Field(alias="from")
    to: DiffEnd
    added: list[DiffSystem]
    removed: list[DiffRemoved]
    changed: list[DiffChanged]
    unchanged: int
