"""Versions of what people edit and their strong ETags (HTTP ``If-Match``, RFC 9110 section 13.1.1).

Two resources are edited: a frame (its ball label, field lines, review and exclusion: ``Frame.edit_version``,
bumped by the writes of that frame only, so a frame's ETag does not change when a sibling view's edit recomputes
it and two annotators on different views of one system do not refuse each other) and a system
(``System.version``, bumped by every write of the rows its edits read: its labels, lines, exclusions,
calibrations, decisions and derived rows; ``app.db.scope``), so a decision sent with the ETag
of a page is refused once anything that page showed has changed. Their ETags are strong and opaque to clients:
``"frame-<id>-<version>"`` and ``"system-<id>-<version>"`` (quotes included, as HTTP writes them).

A write checks the client's expected versions against the rows it read (:func:`check_expected`) and bumps the
version in memory; the write's compare of the system's version under its lock (``app.services.curation.writing``)
makes that check hold at the commit: a frame or decision changed since was written with its system's version.
"""
from __future__ import annotations

import re
from collections.abc import Collection
from typing import Optional

from app.core.errors import StaleVersionError
from app.db.models import Frame, System

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
    """The system's current ETag (:func:`etag` of its ``version``)."""
    return etag("system", system.id, system.version)


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


def check_expected(kind: str, ident: int, current: int, expected: Optional[Collection[int]]) -> None:
    """Refuse a write of resource ``kind`` ``ident`` whose version is ``current`` when the client expected another
    (``expected``: :func:`expected_versions`; None accepts any).

    Raises:
        StaleVersionError: ``current`` is not in ``expected`` (the API answers 412 with the current state).

    >>> check_expected("frame", 4, 2, {2, 5}), check_expected("frame", 4, 2, None)
    (None, None)
    """
    if expected is not None and current not in expected:
        seen = max((v for v in expected if v < current), default=None)  # the page's version: what it did not see
        raise StaleVersionError(kind, ident, etag(kind, ident, current), seen)
