"""Errors the services raise; the API maps them to HTTP statuses and the CLI to messages.

* :class:`NotFoundError` (a ``LookupError``): an id that names no row (HTTP 404).
* :class:`InvalidInputError` (a ``ValueError``): input that cannot be stored: a label, a line set,
  a review status (HTTP 422). Nothing is written when it is raised.
* :class:`DatasetError` (an ``InvalidInputError``): a dataset file that cannot be imported; it names
  the file and the field at fault. Nothing is written when it is raised.
* :class:`StaleVersionError`: a write whose expected version (``If-Match``) is stale (HTTP 412).
* :class:`ConflictError`: a write the current state forbids, e.g. a revert of a changed resource (HTTP 409).
* :class:`ForbiddenError` (a ``PermissionError``): a request the service refuses whatever its content,
  e.g. a server path outside the data root (HTTP 403). Its message never says whether a path exists.
"""
from __future__ import annotations

from pathlib import Path
from typing import TypeVar

T = TypeVar("T")


class ServiceError(Exception):
    """Base class of the errors services raise on purpose."""


class NotFoundError(ServiceError, LookupError):
    """No row has the given id; ``kind`` is "system", "frame", ..."""

    def __init__(self, kind: str, ident: object) -> None:
        super().__init__(f"{kind} {ident!r} not found")
        self.kind = kind
        self.ident = ident


def found(row: T | None, kind: str, ident: object) -> T:
    """``row`` (a lookup's result), or :class:`NotFoundError` naming ``kind`` and ``ident`` when it is None.

    >>> found(3, "frame", 7)
    3
    """
    if row is None:
        raise NotFoundError(kind, ident)
    return row


class InvalidInputError(ServiceError, ValueError):
    """Input that cannot be stored. ``field`` names the offending field when known."""

    def __init__(self, message: str, *, field: str | None = None) -> None:
        super().__init__(f"{field}: {message}" if field else message)
        self.field = field


class DatasetError(InvalidInputError):
    """A dataset file that cannot be imported.

    The message reads ``<file>: <field>: <problem>``; ``file`` may be a path or
    ``archive.zip!member``.
    """

    def __init__(self, file: str | Path, field: str | None, message: str) -> None:
        self.file = str(file)
        ServiceError.__init__(self, f"{self.file}: {field}: {message}" if field else f"{self.file}: {message}")
        self.field = field


class EntryError(DatasetError):
    """A value of one entry of a game's labels that cannot be stored (a ball label the shared check refuses:
    ``app.datasets.labels``), as opposed to a file that is not of its format or reaches outside the dataset: an
    import that reads its games one by one leaves that game out, naming the file, the entry and why
    (``problem``), and imports the others."""

    def __init__(self, file: str | Path, field: str | None, problem: str) -> None:
        super().__init__(file, field, problem)
        self.problem = problem


class ForbiddenError(ServiceError, PermissionError):
    """A request the service refuses on principle (not for its content): HTTP 403."""


class StaleVersionError(ServiceError):
    """A write's expected version (HTTP ``If-Match``) is not the resource's current one: nothing was
    changed (HTTP 412). ``kind`` is "frame" or "system", ``etag`` the current strong ETag; the services
    fill ``current`` (the resource now: the ``Frame`` loaded for its view, or the ``System`` with its
    review) and ``last_change`` (its newest ``AuditEntry``, or None) after rolling back, so the client can
    be shown who changed it and to what. ``seen`` is the newest version the client named below the current one
    (None: it named none); for a system the services also fill ``changes``, the entries after ``seen`` (oldest
    first): what changed since the client read it."""

    def __init__(self, kind: str, ident: int, etag: str, seen: int | None = None) -> None:
        super().__init__(f"{kind} {ident} was changed since the version you sent, by another user or by you "
                         f"elsewhere (it is now {etag}): nothing was stored; reload it, then apply your change again")
        self.kind, self.ident, self.etag, self.seen = kind, ident, etag, seen
        self.current: object | None = None
        self.last_change: object | None = None
        self.changes: list[object] = []


class ConflictError(ServiceError):
    """A write refused because of the resource's current state (HTTP 409), e.g. reverting an audit entry
    whose resource changed since; ``current`` holds that state when known."""

    def __init__(self, message: str, current: object = None) -> None:
        super().__init__(message)
        self.current = current
