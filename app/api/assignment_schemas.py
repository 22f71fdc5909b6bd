"""Request and response models of work assignment and presence:
``POST /api/assignments``, ``GET /api/assignees``, ``PUT`` / ``DELETE /api/systems/{id}/presence``, and the
``assignment`` / ``open_by`` fields of the queue rows and of the system view."""
from __future__ import annotations

from datetime import datetime
from typing import Optional

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.api.schemas import DbInt, QueueQuery, _In
from app.services.curation import presence
from app.services.curation.assignment import Assignment
from app.services.curation.presence import Presence

#: Most systems one request may name by id (a game or a filter selects any number).
MAX_SYSTEM_IDS = 10_000


class AssignmentOut(BaseModel):
    """Who a system is assigned to: ``assignee`` (a user's name, None: nobody), since ``assigned_at``, by
    ``assigned_by`` (None when it never was)."""

    assignee: Optional[str] = Field(description="The assignee's user name; null: unassigned.")
    assigned_at: Optional[datetime] = Field(description="When it was last assigned or unassigned (UTC).")
    assigned_by: Optional[str] = Field(description="Who last assigned or unassigned it.")

    @classmethod
    def of(cls, a: Optional[Assignment]) -> "AssignmentOut":
        """From the service's record (None: never assigned)."""
        if a is None:
            return cls(assignee=None, assigned_at=None, assigned_by=None)
        return cls(assignee=a.assignee, assigned_at=a.assigned_at, assigned_by=a.assigned_by)


class PresenceOut(BaseModel):
    """One person who has a system open now (a live soft claim, ``app.services.curation.presence``)."""

    name: str = Field(description="The user's name.")
    since: datetime = Field(description="When they opened it (UTC; kept while the claim stays live).")
    seconds_open: int = Field(description="Seconds since `since`, by the server's clock (for 'since 2 min').")
    expires_at: datetime = Field(description="When the claim lapses unless the page refreshes it (UTC).")

    @classmethod
    def of(cls, p: Presence, now: datetime) -> "PresenceOut":
        """From the service's claim, its age measured at ``now``."""
        return cls(name=p.name, since=p.since, seconds_open=max(0, int((now - p.since).total_seconds())),
                   expires_at=p.expires_at)


class PresenceStateOut(BaseModel):
    """The answer of a presence heartbeat: the caller's claim, the others who have the system open, and the
    timing the page should keep."""

    mine: PresenceOut
    others: list[PresenceOut] = Field(description="Others with a live claim on the system, oldest first.")
    wrote: bool = Field(description="Whether this heartbeat wrote the database (only when the claim was due).")
    heartbeat_seconds: int = Field(description="How often the page should send the heartbeat while open.")
    ttl_seconds: int = Field(description="How long a claim lives without a refresh.")

    @classmethod
    def of(cls, claimed: presence.Claimed, now: datetime) -> "PresenceStateOut":
        """From the service's answer."""
        return cls(mine=PresenceOut.of(claimed.mine, now), others=[PresenceOut.of(p, now) for p in claimed.others],
                   wrote=claimed.wrote, heartbeat_seconds=int(presence.HEARTBEAT.total_seconds()),
                   ttl_seconds=int(presence.TTL.total_seconds()))


class AssignFilter(QueueQuery):
    """The queue's filters in a request body: unknown keys refused (a misspelt filter must not widen the
    selection to every system)."""

    model_config = ConfigDict(allow_inf_nan=False, extra="forbid")


class AssignIn(_In):
    """Assign systems to a user (``assignee``: a name) or unassign them (``assignee`` null); select them with
    exactly one of ``system_ids``, ``game_id`` and ``filter``."""

    assignee: Optional[str] = Field(..., min_length=1, max_length=100, pattern=r"^[^\x00]*$",
                                    description="An enabled user's name; null clears the assignee.")
    system_ids: Optional[list[DbInt]] = Field(None, min_length=1, max_length=MAX_SYSTEM_IDS,
                                              description="These systems (one or more ids).")
    game_id: Optional[DbInt] = Field(None, description="Every system of this game.")
    filter: Optional[AssignFilter] = Field(
        None, description="Every system the review queue's filters match, across all its pages: the query parameters "
                          "of GET /api/systems as an object (status, game_id, jac_min, ..., doubt, assignee; sort is "
                          "ignored), e.g. {\"status\": \"pending\", \"doubt\": \"any\"}.")

    @model_validator(mode="after")
    def _one_selector(self) -> "AssignIn":
        given = [k for k in ("system_ids", "game_id", "filter") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of system_ids, game_id and filter")
        return self


class AssignedOut(BaseModel):
    """What an assignment did."""

    assignee: Optional[str] = Field(description="The new assignee; null: unassigned.")
    matched: int = Field(description="Systems selected.")
    changed: int = Field(description="Systems whose assignee changed (one audit entry each, action system.assign).")
    system_ids: list[int] = Field(description="The ids of the changed systems, ascending.")


class AssigneeOut(BaseModel):
    """A user systems may be assigned to."""

    name: str
    role: str
