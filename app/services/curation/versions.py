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
from typing import Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session
from sqlalchemy.orm.attributes import set_committed_value

from app.db.models import Frame, System
from app.core.errors import NotFoundError, StaleVersionError

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


def claim_frame(session: Session, frame_id: int, expected: Optional[Collection[int]], *, expire: bool = True) -> None:
    """Bump the frame's ``edit_version`` if it is one of ``expected`` (any when None), in the caller's
    transaction, whose caller has locked the frame's system (``app.services.curation.writing.lock_system``, as the
    guarded write does); then expire the session so that everything read afterwards is the state under the lock
    (``expire`` False: an edit that compared its loaded rows with the stored ones under the lock keeps its objects;
    the frame's ``edit_version`` in memory is set to the new one).

    Raises:
        NotFoundError: no such frame.
        StaleVersionError: its version is not in ``expected`` (nothing changed; the caller rolls back).
    """
    _compare_and_set(session, Frame, Frame.edit_version, "frame", frame_id, expected, expire=expire)


def claim_system_review(session: Session, system_id: int, expected: Optional[Collection[int]]) -> None:
    """Bump the system's ``review_version`` if it is one of ``expected`` (any when None), in the
    caller's transaction; then expire the session (see :func:`claim_frame`).

    Raises:
        NotFoundError: no such system.
        StaleVersionError: its version is not in ``expected``.
    """
    _compare_and_set(session, System, System.review_version, "system", system_id, expected)


@functools.cache
def _claim_statement(model: type, key: str, with_expected: bool, returning: bool) -> sa.Update:
    """The compare-and-set of :func:`_compare_and_set` on ``model``'s column ``key``, taking ``ident`` (and the
    expanding ``expected``); ``RETURNING`` the new version where the database has it. Built once per shape."""
    table = model.__table__
    column = table.c[key]
    stmt = sa.update(table).where(table.c.id == sa.bindparam("ident")).values({key: column + 1})
    if with_expected:
        stmt = stmt.where(column.in_(sa.bindparam("expected", expanding=True)))
    return stmt.returning(column) if returning else stmt


def _compare_and_set(session: Session, model: type, column: sa.orm.InstrumentedAttribute, kind: str, ident: int,
                     expected: Optional[Collection[int]], *, expire: bool = True) -> None:
    returning = session.get_bind().dialect.update_returning  # SQLite >= 3.35 and PostgreSQL: the new version at once
    params = {"ident": ident} if expected is None else {"ident": ident, "expected": sorted(expected)}
    result = session.execute(_claim_statement(model, column.key, expected is not None, returning), params)
    if returning:
        new = result.scalar_one_or_none()
    else:
        new = session.scalar(sa.select(column).where(model.id == ident)) if result.rowcount == 1 else None
    if new is None:
        current = session.scalar(sa.select(column).where(model.id == ident))
        if current is None:
            raise NotFoundError(kind, ident)
        raise StaleVersionError(kind, ident, etag(kind, ident, current))
    if expire:
        session.expire_all()
        return
    loaded = session.identity_map.get(session.identity_key(model, ident))  # type: ignore[arg-type]
    if loaded is not None:
        set_committed_value(loaded, column.key, new)
