"""The audit log: one append-only entry per accepted write, recorded in the write's own transaction.

An entry says who (``actor``: the user's name, or ``cli:<os user>`` for work run on the machine, see
:func:`local_actor`; the OS account is shown to admins only, the other roles read ``cli``: :func:`shown_actor`),
when (UTC), what (``action``, :data:`ACTIONS`) and the state of the edited part before and after the write, as
self-describing JSON: ``{"ball": {"box", "point"}}``,
``{"lines": {class: polylines}}``, ``{"excluded": bool}``, ``{"review": {"status", "comment"}}`` or
``{"calibration_review": {"status", "comment"}}`` (a view's calibration decision) or ``{"assignee": name}``
(a system's assignee, ``app.services.curation.assignment``), or ``{"system": {"review", "views"}}`` (what an import's
merge changed of a stored system, action ``system.import``: ``app.services.curation.states.system_import_state``).
An import or a full recompute is one entry of its own (:func:`record_summary`: its counts in
``after``, no ``before``); they cannot be reverted (``app.services.curation.reverting``), nor can an
administrator's change of a user or a token (:data:`ADMIN_ACTIONS`, listed to admins only). Entries name their
frame, system and game by id without foreign keys, so history outlives the rows it talks about.

A state larger than :data:`LARGE_STATE_BYTES` as JSON (a field-line edit's polylines: about 70 KB at the point cap)
is stored once, compressed, under the digest of its canonical JSON (``audit_states``, :func:`stored_state`): an
edit's state after is the next edit's state before, an undo's are the edit's, so a series of edits of one view adds
one compressed state per edit instead of two whole ones. Readers see ``entry.before`` / ``entry.after`` as before.
"""
from __future__ import annotations

import getpass
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Optional, cast

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from app.core.errors import InvalidInputError
from app.db.models import AuditEntry, AuditState, Frame, System
from app.db.types import canonical_json, compressed_json, json_digest, json_safe, utcnow
from app.services.audit.summaries import summarize

#: The response header naming the audit entry of a write (what a later undo names).
AUDIT_ENTRY_HEADER = "X-V3D-Audit-Entry"
#: Actions that change many rows at once and are never reverted.
SUMMARY_ACTIONS = ("import", "recompute")
#: An administrator's changes of users and tokens (``app.services.accounts.users``): listed to admins only,
#: never reverted (``after`` names the user and the token id, never a secret).
ADMIN_ACTIONS = ("user.create", "user.role", "user.disable", "user.enable", "token.issue", "token.revoke",
                 "user.take_over")
#: Releases made (``app.services.releases.content``): immutable, never reverted.
RELEASE_ACTIONS = ("release.create",)
#: The team's loop (``app.services.curation.handoff`` and ``comments``): a needs-fix system returned to a person or
#: sent back as fixed, a comment pinned on a view, resolved or reopened. Recorded in words, never reverted (a hand-off
#: follows a decision, which is reverted itself; a comment is resolved or reopened instead).
TEAM_ACTIONS = ("system.handoff", "comment.add", "comment.resolve", "comment.reopen")
#: Every action an entry may record.
ACTIONS = ("ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion", "view.review",
           "view.calibration_review", "system.review", "system.assign", "system.import", *SUMMARY_ACTIONS, "revert",
           *ADMIN_ACTIONS, *RELEASE_ACTIONS, *TEAM_ACTIONS)


def revertible(action: str) -> bool:
    """Whether an entry of ``action`` can be reverted: an edit of one resource, not an import or a
    recompute (many rows) nor an administrator's change of a user or a token.

    >>> revertible("ball.edit"), revertible("import"), revertible("token.revoke")
    (True, False, False)
    """
    return (action not in SUMMARY_ACTIONS and action not in ADMIN_ACTIONS and action not in RELEASE_ACTIONS
            and action not in TEAM_ACTIONS)


#: How work run on the machine is named to every role but admins, and in the text every role reads (a reset
#: reason, an assignment's ``assigned_by``): the OS account behind it is the machine's business, and to anyone else
#: only the name of an account to try.
MACHINE_ACTOR = "cli"


def shown_actor(actor: str, admin: bool) -> str:
    """An entry's ``actor`` as a reader sees it: the stored name for an admin; for the other roles
    :data:`MACHINE_ACTOR` in place of ``cli:<os user>``.

    >>> shown_actor("cli:root", admin=False), shown_actor("cli:root", admin=True), shown_actor("ana", admin=False)
    ('cli', 'cli:root', 'ana')
    """
    return actor if admin or not actor.startswith(f"{MACHINE_ACTOR}:") else MACHINE_ACTOR


def public_actor(actor: Optional[str]) -> str:
    """Who made a write, as text every role reads (a decision's reset reason, an assignment's ``assigned_by``):
    the user's name, or :data:`MACHINE_ACTOR` for work run on the machine (``actor`` None; its OS account stays in the
    audit entry, for admins)."""
    return actor or MACHINE_ACTOR


def actor_words(actor: Optional[str], admin: bool) -> str:
    """Who made something, in a reader's words: the user's name, or ``command line`` for work run on the machine
    (``command line (<os user>)`` to an admin, as :func:`shown_actor` shows the OS account to admins only).

    >>> actor_words("cli:root", admin=True), actor_words("cli:root", admin=False), actor_words("ana", admin=False)
    ('command line (root)', 'command line', 'ana')
    """
    if not actor or actor == MACHINE_ACTOR:
        return "command line"
    if actor.startswith(f"{MACHINE_ACTOR}:"):
        return f"command line ({actor.split(':', 1)[1]})" if admin else "command line"
    return actor


def local_actor() -> str:
    """``cli:<os user>``: the actor of writes made on the machine (CLI, scripts calling the services),
    whose owner needs no v3d account (shown to admins only: :func:`shown_actor`)."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):  # no user name in a bare container
        user = "unknown"
    return f"cli:{user}"


def record(session: Session, *, actor: Optional[str], action: str, frame: Optional[Frame] = None,
           system: Optional[System] = None, before: Any = None, after: Any = None,
           reverts_id: Optional[int] = None, facts: Optional[dict[str, Any]] = None) -> AuditEntry:
    """Add one entry to the session (the caller's transaction commits it with the write) and return it.

    ``reverts_id``: the entry this write undoes: a revert (action ``revert``), or a page's undo of its own edit,
    audited as that edit's action (``app.services.curation.editing.replace_field_lines``' ``undo_of``).
    ``frame`` sets ``frame_id``, ``system_id`` and ``game_id``; ``system`` alone sets the last two, and the system's
    version as it is now (``system_version``; a write that bumps it after recording calls :func:`stamp_versions`).
    ``facts``: what only the running write knows, for the summary (``calibration=(before, after)`` in words,
    ``app.services.audit.summaries.summarize``). ``actor`` None is :func:`local_actor`. Raises ``ValueError`` for an
    action outside :data:`ACTIONS`.
    """
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}")
    system = frame.system if frame is not None else system
    before = json_safe(before) if before is not None else None
    after = json_safe(after) if after is not None else None
    entry = AuditEntry(
        at=utcnow(), actor=actor or local_actor(), action=action, frame_id=frame.id if frame is not None else None,
        system_id=system.id if system is not None else None, game_id=system.game_id if system is not None else None,
        reverts_id=reverts_id,
        system_version=system.version if system is not None else None,
        summary=summarize(action, before, after, view=view_name(frame) if frame is not None else None,
                          reverts_id=reverts_id, facts=facts,
                          redo=action != "revert" and _is_undo(session, reverts_id))[:SUMMARY_MAX],
    )
    entry.before_inline, entry.before_state = stored_state(session, before)
    entry.after_inline, entry.after_state = stored_state(session, after)
    session.add(entry)
    return entry


@dataclass(frozen=True)
class SystemChange:
    """One system's change in a write of many (:func:`record_many`): its id, game id, the version the write gives it,
    its part's state before and after (small states: a decision's), and the entry it undoes (None)."""

    system_id: int
    game_id: int
    system_version: int
    before: dict[str, Any]
    after: dict[str, Any]
    reverts_id: Optional[int] = None


def record_many(session: Session, *, actor: Optional[str], action: str, changes: list[SystemChange]) -> None:
    """One entry per change of a write that changes many systems at once (a batch's acceptance after a sample,
    ``app.services.curation.batches``), inserted by one statement in the caller's transaction, each as
    :func:`record` would write it (its summary, its states inline, the version the write gives its system). A state
    must be small (:data:`LARGE_STATE_BYTES`): a decision's is.

    Raises:
        ValueError: an action outside :data:`ACTIONS`, or a state too large to be stored inline.
    """
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}")
    now, who = utcnow(), actor or local_actor()
    rows = []
    for c in changes:
        before, after = json_safe(c.before), json_safe(c.after)
        if max(len(canonical_json(before)), len(canonical_json(after))) >= LARGE_STATE_BYTES:
            raise ValueError(f"system {c.system_id}: a state too large to be recorded with many others")
        rows.append({"at": now, "actor": who, "action": action, "system_id": c.system_id, "game_id": c.game_id,
                     "system_version": c.system_version, "reverts_id": c.reverts_id,
                     "before_inline": before, "after_inline": after,
                     "summary": summarize(action, before, after, reverts_id=c.reverts_id)[:SUMMARY_MAX]})
    if rows:
        session.execute(sa.insert(AuditEntry), rows)


def record_selected(session: Session, *, actor: Optional[str], action: str, systems: sa.Select[int, int, int],
                    before: dict[str, Any], after: dict[str, Any]) -> None:
    """One entry per row of ``systems`` for a write that gives many systems the same change (a batch's acceptance
    after a sample, ``app.services.curation.batches``): one ``INSERT ... SELECT`` in the caller's transaction, so
    its cost does not grow with a Python object, a bound row and a summary per system. Each entry is the one
    :func:`record_many` would write for that system (its summary, both states inline, the version the write gives
    it). The database assigns the entries' ids in ``systems``' order.

    Args:
        systems: a select of three columns per system: its id, its game's id and the version the write gives it.
        before, after: the state of every selected system before and after (small states: a decision's).

    Raises:
        ValueError: an action outside :data:`ACTIONS`, or a state too large to be stored inline.
    """
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}")
    before, after = json_safe(before), json_safe(after)
    if max(len(canonical_json(before)), len(canonical_json(after))) >= LARGE_STATE_BYTES:
        raise ValueError("a state too large to be recorded with many others")
    table = cast(sa.Table, AuditEntry.__table__)
    rows = systems.subquery()
    sid, gid, version = rows.c
    constants = {"at": utcnow(), "actor": actor or local_actor(), "action": action, "before": before, "after": after,
                 "summary": summarize(action, before, after)[:SUMMARY_MAX]}
    columns = [sa.literal(value, type_=table.c[name].type).label(name) for name, value in constants.items()]
    select = sa.select(*columns, sid, gid, version).select_from(rows).order_by(sid)
    session.execute(sa.insert(table).from_select([*constants, "system_id", "game_id", "system_version"], select,
                                                 include_defaults=False))


#: States (before / after) whose canonical JSON is at least this long (bytes) are stored once, compressed, in
#: ``audit_states`` (a ball label or a decision stays inline; a frame's field lines, 61-71 points in the real sets,
#: are about 2-3 KB).
LARGE_STATE_BYTES = 1024


def stored_state(session: Session, state: Optional[dict[str, Any]]) -> tuple[Optional[dict[str, Any]],
                                                                           Optional[AuditState]]:
    """Where an entry keeps ``state`` (JSON-safe already): ``(state, None)`` inline when it is small, else ``(None,
    row)`` with the :class:`AuditState` row of its digest, inserted unless a row of that digest exists (``ON
    CONFLICT DO NOTHING``: two writers storing the same state at once never collide; the second waits for the
    first's commit and then reads its row, as PostgreSQL's read committed isolation and SQLite's single writer
    allow). In the caller's write transaction; the session is not flushed (the caller's changes are flushed, and
    compared, by the caller)."""
    if state is None:
        return None, None
    canonical = canonical_json(state)
    if len(canonical) < LARGE_STATE_BYTES:
        return state, None
    digest = json_digest(canonical)
    with session.no_autoflush:
        row = session.get(AuditState, digest)
        if row is None:
            dialect = session.get_bind().dialect.name
            insert = (postgresql.insert if dialect == "postgresql" else sqlite.insert)(AuditState)
            session.execute(insert.values(digest=digest, body=compressed_json(canonical))
                            .on_conflict_do_nothing(index_elements=[AuditState.digest]))
            row = session.get(AuditState, digest)
    assert row is not None  # inserted or found above, in this transaction
    return None, row


def stamp_versions(session: Session, system: System) -> None:
    """Give every entry of ``system`` the write is adding (``session.new``) the version the write gives the system
    (``System.version`` once it was bumped): one write's entries share it, whenever each was recorded."""
    for entry in session.new:
        if isinstance(entry, AuditEntry) and entry.system_id == system.id:
            entry.system_version = system.version


#: The longest summary stored (characters; ``audit_entries.summary``).
SUMMARY_MAX = 300


def _is_undo(session: Session, entry_id: Optional[int]) -> bool:
    """Whether entry ``entry_id`` is an undo (an edit naming the entry it undoes) and not itself a redo: an undo
    of it is then a redo. Follows the chain of undos (undo, redo, undo, ...) back to the edit."""
    depth = 0
    while entry_id is not None and depth < 1000:
        row = session.execute(
            sa.select(AuditEntry.action, AuditEntry.reverts_id).where(AuditEntry.id == entry_id)).first()
        if row is None or row.action == "revert" or row.reverts_id is None:
            break
        depth += 1
        entry_id = row.reverts_id
    return depth % 2 == 1


def view_name(frame: Frame) -> str:
    """The view's name on the system page: "V<n>", n its place among its system's views (``Frame.position``
    order, as the page lists them), 1-based."""
    frames = frame.system.frames if frame.system is not None else []
    index = next((i for i, f in enumerate(frames) if f.id == frame.id), None)
    return f"V{index + 1}" if index is not None else f"frame {frame.id}"


def entry_summary(entry: AuditEntry, view: Optional[str] = None) -> str:
    """The entry's stored summary, or (an entry recorded before summaries were) the one computed from its
    states by the same function (``view``: its view's name on the page, when known)."""
    if entry.summary:
        return entry.summary
    return summarize(entry.action, entry.before, entry.after, view=view, reverts_id=entry.reverts_id)[:SUMMARY_MAX]


def view_names(session: Session, entries: list[AuditEntry]) -> dict[int, str]:
    """Frame id -> "V<n>" for the frames the ``entries`` name (one query over their systems' views)."""
    systems = {e.system_id for e in entries if e.frame_id is not None and e.system_id is not None}
    if not systems:
        return {}
    rows = session.execute(sa.select(Frame.id, Frame.system_id).where(Frame.system_id.in_(systems))
                           .order_by(Frame.system_id, Frame.position, Frame.id)).all()
    out: dict[int, str] = {}
    place: dict[int, int] = {}
    for frame_id, system_id in rows:
        place[system_id] = place.get(system_id, 0) + 1
        out[frame_id] = f"V{place[system_id]}"
    return out


def record_summary(session: Session, action: str, counts: dict[str, Any], *, actor: Optional[str] = None,
                   game_id: Optional[int] = None) -> AuditEntry:
    """One entry for a whole import or recompute (``action`` in :data:`SUMMARY_ACTIONS`), its ``counts``
    (e.g. source, games, systems, frames) in ``after``; added to the session of the batch that commits last."""
    if action not in SUMMARY_ACTIONS:
        raise ValueError(f"{action!r} is not a summary action")
    entry = AuditEntry(actor=actor or local_actor(), action=action, game_id=game_id, after=json_safe(counts))
    session.add(entry)
    return entry


@dataclass(frozen=True)
class AuditPage:
    """One page of entries, newest first, and how many match."""

    items: list[AuditEntry]
    total: int


def _conditions(frame_id: Optional[int], system_id: Optional[int], user: Optional[str],
                include_admin: bool = True) -> list[Any]:
    """The filters of :func:`list_entries`; for a non-admin (``include_admin`` False) ``user`` matches actors as
    :func:`shown_actor` shows them: ``cli`` every ``cli:<os user>``, a ``cli:<os user>`` nothing."""
    out: list[sa.ColumnElement[bool]] = [] if include_admin else [AuditEntry.action.not_in(ADMIN_ACTIONS)]
    if frame_id is not None:
        out.append(AuditEntry.frame_id == frame_id)
    if system_id is not None:
        out.append(AuditEntry.system_id == system_id)
    if user is not None and not include_admin and user.startswith(MACHINE_ACTOR):
        out.append(AuditEntry.actor.startswith(f"{MACHINE_ACTOR}:", autoescape=True) if user == MACHINE_ACTOR
                   else sa.false())
    elif user is not None:
        out.append(AuditEntry.actor == user)
    return out


@dataclass(frozen=True)
class EntryFilter:
    """Which entries a listing takes: every given filter holds. ``system_id`` matches the system's own decisions and
    every edit of its views; ``user`` is an actor's exact name; ``include_admin`` False leaves out
    :data:`ADMIN_ACTIONS` and reads ``user`` as a non-admin sees the actors (:func:`shown_actor`: ``cli`` for work on
    the machine, never its OS account). ``since`` and ``until`` (timezone-aware) bound when the entry was written:
    at or after ``since``, before ``until`` (a reader's day is ``since`` its midnight, ``until`` the next one).

    Raises:
        InvalidInputError: ``until`` not after ``since`` (field ``until``), or either without a time zone (its field).
    """

    frame_id: Optional[int] = None
    system_id: Optional[int] = None
    user: Optional[str] = None
    include_admin: bool = True
    since: Optional[datetime] = None
    until: Optional[datetime] = None

    def __post_init__(self) -> None:
        for name in ("since", "until"):
            when = getattr(self, name)
            if when is not None and when.utcoffset() is None:
                raise InvalidInputError(f"{when.isoformat()} names no time zone: add one (Z for UTC)", field=name)
        if self.since is not None and self.until is not None and self.until <= self.since:
            raise InvalidInputError(f"{self.until.isoformat()} is not after since ({self.since.isoformat()}): no "
                                    "entry could be written in between", field="until")

    def conditions(self) -> list[Any]:
        """The filters as SQL conditions on ``AuditEntry``."""
        out = _conditions(self.frame_id, self.system_id, self.user, self.include_admin)
        if self.since is not None:
            out.append(AuditEntry.at >= self.since)
        if self.until is not None:
            out.append(AuditEntry.at < self.until)
        return out


def list_entries(session: Session, *, frame_id: Optional[int] = None, system_id: Optional[int] = None,
                 user: Optional[str] = None, limit: int = 50, offset: int = 0,
                 include_admin: bool = True) -> AuditPage:
    """Entries matching every given filter (:class:`EntryFilter`), newest first (by id, the commit order of their
    writes), and how many match."""
    which = EntryFilter(frame_id, system_id, user, include_admin)
    items = [e for batch in entry_batches(session, which, limit=limit, offset=offset) for e in batch]
    return AuditPage(items=items, total=count_entries(session, which))


def count_entries(session: Session, which: EntryFilter) -> int:
    """How many entries ``which`` takes."""
    return int(session.scalar(sa.select(sa.func.count()).select_from(AuditEntry).where(*which.conditions())) or 0)


#: Entries read from the database at a time by :func:`entry_batches`.
ENTRY_BATCH = 8


def entry_batches(session: Session, which: EntryFilter, *, limit: int = 50,
                  offset: int = 0) -> Iterator[list[AuditEntry]]:
    """The entries ``which`` takes, newest first, from the ``offset``-th, at most ``limit``, read :data:`ENTRY_BATCH`
    at a time from the database (a server-side cursor on PostgreSQL): a caller that stops early (an answer full at
    its byte cap) never loads the rest, and the entries it is done with can be freed while it reads on."""
    stmt = (sa.select(AuditEntry).where(*which.conditions()).order_by(AuditEntry.id.desc()).limit(limit)
            .offset(offset).execution_options(yield_per=ENTRY_BATCH))
    result = session.scalars(stmt)
    try:
        for batch in result.partitions():
            yield list(batch)
    finally:
        result.close()


def latest_entry(session: Session, *, frame_id: Optional[int] = None,
                 system_id: Optional[int] = None) -> Optional[AuditEntry]:
    """The newest entry of a frame (``frame_id``) or of a system's own decisions (``system_id`` alone:
    entries without a frame); None when there is none."""
    where = _conditions(frame_id, system_id, None)
    if frame_id is None:
        where.append(AuditEntry.frame_id.is_(None))
    entry = session.scalars(sa.select(AuditEntry).where(*where).order_by(AuditEntry.id.desc()).limit(1)).first()
    return entry


#: The most entries :func:`entries_since` answers (the newest of them).
SINCE_MAX = 20


def entries_since(session: Session, system_id: int, version: int, limit: int = SINCE_MAX) -> list[AuditEntry]:
    """The entries of system ``system_id`` (its views' edits, its decisions) written after its version ``version``
    (``system_version`` above it), oldest first: at most the ``limit`` newest. Entries recorded before versions were
    (``system_version`` NULL) are not among them."""
    rows = session.scalars(sa.select(AuditEntry).where(AuditEntry.system_id == system_id,
                                                       AuditEntry.system_version > version)
                           .order_by(AuditEntry.id.desc()).limit(limit))
    return list(rows)[::-1]


def entries_of_write(session: Session, entry: AuditEntry) -> list[AuditEntry]:
    """The entries the write that recorded ``entry`` recorded before it (the same system and ``system_version``, a
    lower id: e.g. the decisions an edit set back to pending), in id order; none when ``entry`` has no version."""
    if entry.system_id is None or entry.system_version is None:
        return []
    return list(session.scalars(sa.select(AuditEntry).where(
        AuditEntry.system_id == entry.system_id, AuditEntry.system_version == entry.system_version,
        AuditEntry.id < entry.id).order_by(AuditEntry.id)))


def entries_after(session: Session, entry: AuditEntry, limit: int) -> Optional[list[AuditEntry]]:
    """The entries of ``entry``'s system written after it (a higher id: the writes of one system commit in turn),
    oldest first; None when there are more than ``limit``."""
    rows = list(session.scalars(sa.select(AuditEntry).where(
        AuditEntry.system_id == entry.system_id, AuditEntry.id > entry.id).order_by(AuditEntry.id).limit(limit + 1)))
    return rows if len(rows) <= limit else None
