"""Pydantic schemas of the audit log's API (``/api/audit``), apart from ``schemas.py`` to keep it small."""
from __future__ import annotations

from datetime import datetime
from typing import Any, Optional

from pydantic import BaseModel, ConfigDict, Field, computed_field, model_validator

from app.api.schemas import DB_INT_MAX, DbInt, QueryText, UtcTime
from app.services.audit import log as audit
from app.services.audit.summaries import summarize


class AuditEntryOut(BaseModel):
    """One audited write (``app.services.audit.log``): who, when, what, the edited part before and after
    (``{"ball": {box, point}}``, ``{"lines": {...}}``, ``{"excluded": bool}``, ``{"review": {status,
    comment}}``; an import's or recompute's counts in ``after``). Read from the ``AuditEntry`` row."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    at: datetime
    actor: str = Field(description="The user's name (work run on the machine: cli:<os user> to admins, cli to the "
                                   "other roles).")
    action: str
    frame_id: Optional[int]
    system_id: Optional[int]
    game_id: Optional[int]
    before: Optional[dict[str, Any]]
    after: Optional[dict[str, Any]]
    reverts_id: Optional[int] = Field(description="A revert (action `revert`) or an undo (the edit's own action): "
                                                  "the entry it undid.")
    summary: Optional[str] = Field(None, description=(
        "The change in one line of words (\"ball of V2 moved 12.3 px\", \"V3 excluded from the 3D ball\", "
        "\"moved point 9 of Circle right (V3): JaC 0.909 -> refused\", \"system accepted\"), written when the entry "
        "was recorded; for entries older than that, computed from `before` and `after` when read."))

    @classmethod
    def shown(cls, entry: Any, admin: bool) -> "AuditEntryOut":
        """The entry as a reader sees it: its actor through ``app.services.audit.log.shown_actor`` (work run on the
        machine is ``cli`` to every role but admins)."""
        out = cls.model_validate(entry)
        return out if admin else out.model_copy(update={"actor": audit.shown_actor(out.actor, admin=False)})

    @model_validator(mode="after")
    def _summarised(self) -> "AuditEntryOut":
        if not self.summary:  # an entry recorded before summaries, read outside the list (a 412's last change)
            self.summary = summarize(self.action, self.before, self.after, reverts_id=self.reverts_id)
        return self

    @computed_field(  # type: ignore[prop-decorator]  # pydantic: a decorator over @property
        description="False for imports, recomputes and changes of users and tokens.")
    @property
    def revertible(self) -> bool:
        return audit.revertible(self.action)


class AuditPageOut(BaseModel):
    """A page of the audit log, newest first."""

    items: list[AuditEntryOut]
    total: int
    limit: int
    offset: int
    next_offset: Optional[int] = Field(None, description="The offset of the next page, null on the last one. A page "
                                                         "stops before V3D_MAX_ANSWER_KB of JSON, so it may hold fewer "
                                                         "than `limit` entries before the last page.")


class AuditQuery(BaseModel):
    """Filters and page of ``GET /api/audit``."""

    frame_id: Optional[DbInt] = Field(None, description="Only this frame's entries.")
    system_id: Optional[DbInt] = Field(None, description="Only this system's entries (its decisions and its views' "
                                                         "edits).")
    user: Optional[QueryText] = Field(None, max_length=200, description="Only this user's entries (exact name).")
    since: Optional[UtcTime] = Field(None, description="Only entries written at or after this time (ISO 8601; UTC "
                                                       "when it names no offset).")
    until: Optional[UtcTime] = Field(None, description="Only entries written before this time (ISO 8601; UTC when it "
                                                       "names no offset); after `since`.")
    limit: int = Field(50, ge=1, le=500)
    offset: int = Field(0, ge=0, le=DB_INT_MAX)
