"""Versions of what people edit, their strong ETags, and the compare-and-set every write starts with.

Two resources are edited: a frame (its ball label, field lines, review and exclusion:
``Frame.edit_version``) and a system's review decision (``System.review_version``). Their ETags are
strong and opaque to clients: ``"frame-<id>-<version>"`` and ``"system-<id>-<version>"`` (quotes
included, as HTTP writes them). A recomputation never bumps a version, so a frame's ETag does not
change when a sibling view's edit recomputes it.

A write claims its resource **inside its transaction** with one ``UPDATE ... SET version = version + 1
WHERE id = :id [AND version IN (:expected)] RETURNING version``: the database checks the expected version
and takes the row's write lock in the same statement (compare-and-set), so two writers holding the same
ETag cannot both succeed, and nothing is read, checked and written across a commit. A frame's claim comes
after its system's row is locked (``SELECT ... FOR UPDATE`` on PostgreSQL; SQLite's write lock covers the
database), so two edits of sibling views recompute their system one after the other.
"""
from __future__ import annotations

import functools
import re
from collections.abc import Collection
from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql
from sqlalchemy.orm import Session
from sqlalchemy.orm.attributes import set_committed_value

from app.db.models import Frame, System
from app.core.errors import NotFoundError, StaleVersionError
from app.db.together import Call

_ETAG = re.compile(r'^"(frame|system)-(\d+)-(\d+)"$')


def etag(kind: str, ident: int, version: int) -> str:
    """The strong ETag of version ``version`` of resource ``kind`` ("frame" or "system") ``ident``.

    >>> etag("frame", 12, 3)
    '"frame-12-3"'
    """
    return f'"{kind}-{int(ident)}-{int(version)}"'


def frame_etag(frame: Frame) -> str:
    """The frame's current ETag (:func:`etag` of its ``edit_version``)."""
    return etag("frame", frame.id, frame.edit_version)


def system_etag(system: System) -> str:
    """The ETag of the system's review decision (:func:`etag` of its ``review_version``)."""
    return etag("system", system.id, system.review_version)


def expected_versions(if_match: Optional[str], kind: str, ident: int) -> Optional[frozenset[int]]:
    """The versions an ``If-Match`` header accepts for resource ``kind`` ``ident``.

    None when there is no header or it is ``*`` (any version); otherwise the versions of the listed
    strong ETags that name this resource, possibly none (weak, foreign or malformed tags never match:
    RFC 9110 section 13.1.1 compares strongly), which makes the write fail with 412.

    >>> sorted(expected_versions('"frame-4-2", "frame-4-5", W/"frame-4-7", "system-4-1"', "frame", 4))
    [2, 5]
    >>> expected_versions("*", "frame", 4) is None, expected_versions('"x"', "frame", 4)
    (True, frozenset())
    """
    if if_match is None or if_match.strip() == "*":
        return None
    out = set()
    for tag in if_match.split(","):
        m = _ETAG.match(tag.strip())
        if m and m.group(1) == kind and int(m.group(2)) == ident:
            out.add(int(m.group(3)))
    return frozenset(out)


@dataclass(frozen=True)
class Claim:
    """The compare-and-set that begins a write (module docstring): bump ``model``'s version column ``key`` of row
    ``ident`` (resource ``kind``: "frame" or "system") if it is one of ``expected`` (any when None).

    Run it at once (``claim(session)``), or send its statement with others (:meth:`call`, ``app.db.together``: on
    PostgreSQL in the round trip of the lock and the digest an edit reads under it, ``app.services.curation.writing``)
    and read its answer (:meth:`settle`). Either way its caller has locked the resource's system first.
    """

    model: type
    key: str
    kind: str
    ident: int
    expected: Optional[frozenset[int]]

    @classmethod
    def frame(cls, frame_id: int, expected: Optional[Collection[int]]) -> "Claim":
        """The claim of frame ``frame_id``'s ``edit_version``."""
        return cls(Frame, "edit_version", "frame", frame_id, None if expected is None else frozenset(expected))

    @classmethod
    def system_review(cls, system_id: int, expected: Optional[Collection[int]]) -> "Claim":
        """The claim of system ``system_id``'s ``review_version``."""
        return cls(System, "review_version", "system", system_id, None if expected is None else frozenset(expected))

    def __call__(self, session: Session, *, expire: bool = True) -> None:
        """Claim now, in the session's transaction; then expire the session so that everything read afterwards is
        the state under the lock (``expire`` False: an edit that compared its loaded rows with the stored ones under
        the lock keeps its objects; the version in memory is set to the new one).

        Raises:
            NotFoundError: no such row.
            StaleVersionError: its version is not in ``expected`` (nothing changed; the caller rolls back).
        """
        dialect = session.get_bind().dialect
        result = session.execute(_claim_statement(self.model, self.key, self.expected is not None,
                                                  dialect.update_returning, dialect.name == "postgresql"),
                                 self._params())
        if dialect.update_returning:
            new = result.scalar_one_or_none()
        else:
            column = self.model.__table__.c[self.key]
            new = session.scalar(sa.select(column).where(column.table.c.id == self.ident)) if result.rowcount == 1 \
                else None
        self._settled(session, new, expire)

    def call(self, dialect: sa.Dialect) -> Call:
        """The claim's statement for ``dialect`` (one that answers the new version: ``UPDATE ... RETURNING``), to send
        with others (``app.db.together.send_together``); its answer goes to :meth:`settle`. On PostgreSQL the
        expected versions are one array parameter (``= ANY``), so the statement is compiled once whatever their
        number."""
        if not dialect.update_returning:
            raise ValueError(f"Claim.call: {dialect.name} has no UPDATE ... RETURNING; call the claim instead")
        return Call(_claim_statement(self.model, self.key, self.expected is not None, True,
                                     dialect.name == "postgresql"), self._params())

    def settle(self, session: Session, rows: list[tuple[Any, ...]], *, expire: bool = True) -> None:
        """Finish the claim whose statement (:meth:`call`) answered ``rows``, as :meth:`__call__` finishes.

        Raises:
            NotFoundError: no such row.
            StaleVersionError: its version is not in ``expected`` (nothing changed; the caller rolls back).
        """
        self._settled(session, rows[0][0] if rows else None, expire)

    def _params(self) -> dict[str, Any]:
        if self.expected is None:
            return {"ident": self.ident}
        return {"ident": self.ident, "expected": sorted(self.expected)}

    def _settled(self, session: Session, new: Optional[int], expire: bool) -> None:
        """Raise for a claim that bumped nothing (the row is gone or its version not expected); else expire the
        session, or set the version in memory (``expire`` False)."""
        column = self.model.__table__.c[self.key]
        if new is None:
            current = session.scalar(sa.select(column).where(column.table.c.id == self.ident))
            if current is None:
                raise NotFoundError(self.kind, self.ident)
            raise StaleVersionError(self.kind, self.ident, etag(self.kind, self.ident, current))
        if expire:
            session.expire_all()
            return
        loaded = session.identity_map.get(session.identity_key(self.model, self.ident))  # type: ignore[arg-type]
        if loaded is not None:
            set_committed_value(loaded, self.key, new)


def claim_frame(session: Session, frame_id: int, expected: Optional[Collection[int]], *, expire: bool = True) -> None:
    """Bump the frame's ``edit_version`` if it is one of ``expected`` (any when None), in the caller's
    transaction, whose caller has locked the frame's system (``app.services.curation.writing.lock_system``, as the
    guarded write does): :class:`Claim` ``.frame`` run at once.

    Raises:
        NotFoundError: no such frame.
        StaleVersionError: its version is not in ``expected`` (nothing changed; the caller rolls back).
    """
    Claim.frame(frame_id, expected)(session, expire=expire)


def claim_system_review(session: Session, system_id: int, expected: Optional[Collection[int]]) -> None:
    """Bump the system's ``review_version`` if it is one of ``expected`` (any when None), in the
    caller's transaction; then expire the session (see :func:`claim_frame`).

    Raises:
        NotFoundError: no such system.
        StaleVersionError: its version is not in ``expected``.
    """
    Claim.system_review(system_id, expected)(session)


@functools.cache
def _claim_statement(model: type, key: str, with_expected: bool, returning: bool, as_array: bool) -> sa.Update:
    """The compare-and-set of :class:`Claim` on ``model``'s column ``key``, taking ``ident`` (and ``expected``: an
    expanding ``IN``, or with ``as_array`` one PostgreSQL array, ``= ANY``); ``RETURNING`` the new version where the
    database has it. Built once per shape."""
    table = model.__table__
    column = table.c[key]
    stmt = sa.update(table).where(table.c.id == sa.bindparam("ident")).values({key: column + 1})
    if with_expected and as_array:
        stmt = stmt.where(column == sa.any_(sa.bindparam("expected", type_=postgresql.ARRAY(sa.Integer))))
    elif with_expected:
        stmt = stmt.where(column.in_(sa.bindparam("expected", expanding=True)))
    return stmt.returning(column) if returning else stmt
