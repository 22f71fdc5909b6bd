"""The errors a v3d client raises: one class per refusal a script handles differently, each with the server's words.

Every answer of 4xx or 5xx is an :class:`APIError` carrying its ``status``, the server's sentence (``detail``) and,
when the server names it, the ``field`` at fault. An answer the route does not promise (not JSON, another shape, a
redirect, past the client's size or time bound) is a :class:`BadAnswer`. The subclasses are the answers a script
reacts to: :class:`EditConflict` (412: someone changed what the edit was made against; it holds the state now and the
changes since), :class:`Busy` (503 or 429 still, after the client's bounded retries), the others by status.
"""
from __future__ import annotations

from typing import Any, Optional

from v3d_client.models import AuditEntry, Frame, Job, Stale, SystemState


class V3DError(Exception):
    """Anything the client refuses or the server refused."""


class VersionMismatch(V3DError):
    """The server's version is not one this client speaks (``v3d_client.version.mismatch`` says why)."""


class Unreachable(V3DError):
    """The server did not answer (no connection, a timeout, the connection cut); the request may not have arrived."""


class BadAnswer(V3DError):
    """The server answered what its route does not promise: the subclasses say how. ``status`` is the answer's HTTP
    status (None when none came); the message names the server, the request and what it answered, in one line."""

    def __init__(self, message: str, status: Optional[int] = None) -> None:
        super().__init__(message)
        self.status = status


class NotJSON(BadAnswer):
    """An answer that is not JSON where the route answers JSON (an HTML page of a proxy, a truncated body)."""


class WrongShape(BadAnswer):
    """JSON of another shape than the route's (a field missing or of another type)."""


class Redirected(BadAnswer):
    """A redirect (3xx): the client never follows one (the token would go where the URL did not name); give the
    server's own URL."""


class AnswerTooLarge(BadAnswer):
    """An answer longer than the client reads into memory (``max_answer_bytes``): refused at the first byte past it."""


class AnswerTooSlow(BadAnswer):
    """An answer not complete within the client's total time for one request (``total_timeout_s``): a body that
    never ends, or one sent a byte at a time."""


class APIError(V3DError):
    """The server refused a request.

    Attributes:
        status: the HTTP status.
        detail: the server's words (for a request FastAPI refused, its messages joined).
        field: the field at fault, when the server names one (``loc`` of a validation error without ``body`` /
            ``query``).
        body: the answer's JSON (or None when it was not JSON).
    """

    def __init__(self, status: int, detail: str, field: Optional[str] = None, body: Any = None) -> None:
        self.status, self.detail, self.field, self.body = status, detail, field, body
        where = f" ({field})" if field and not detail.startswith(f"{field}:") else ""
        super().__init__(f"{status}: {detail}{where}")


class BadRequest(APIError):
    """400: a dataset that cannot be read, a missing path, an unsafe zip (the member named)."""


class Unauthorized(APIError):
    """401: no token or session, or one that no longer works."""


class Forbidden(APIError):
    """403: the role is below the route's (or the path is outside the server's data root)."""


class NotFound(APIError):
    """404: no such id or name."""


class Conflict(APIError):
    """409: refused as things stand (a name taken, games stored already, a job not done); ``current`` is what the
    server says stands in the way (its ``current`` field), when it says."""

    @property
    def current(self) -> Any:
        """The server's ``current`` (e.g. ``{"games": [...]}`` for an import of stored games), or None."""
        return self.body.get("current") if isinstance(self.body, dict) else None


class TooLarge(APIError):
    """413: an upload larger than the server takes."""


class Invalid(APIError):
    """422: invalid input, ``field`` naming it."""


class EditConflict(APIError):
    """412: the edit named a version that is no longer current; nothing was stored.

    Attributes:
        stale: the answer: ``current`` (a :class:`Frame` or :class:`SystemState`, its ``etag`` the version to send
            now), ``last_change`` and ``changes_since`` (for a system, every audit entry since the version sent).
    """

    def __init__(self, status: int, detail: str, field: Optional[str] = None, body: Any = None) -> None:
        super().__init__(status, detail, field, body)
        self.stale = Stale.model_validate(body)

    @property
    def current(self) -> Frame | SystemState | None:
        """The resource as it is now."""
        return self.stale.current

    @property
    def etag(self) -> str:
        """The resource's version now."""
        return self.stale.etag

    @property
    def changes_since(self) -> list[AuditEntry]:
        """The audit entries written since the version the edit named (for a system decision)."""
        return self.stale.changes_since


class PreconditionRequired(APIError):
    """428: a token's write sent no ETag (the client always sends one: a call without the object it read)."""


class Busy(APIError):
    """503 or 429 after the client's retries: the server is busy; nothing was changed. ``retry_after`` is the
    server's last ``Retry-After`` in seconds (None when it sent none)."""

    def __init__(self, status: int, detail: str, field: Optional[str] = None, body: Any = None,
                 retry_after: Optional[float] = None) -> None:
        super().__init__(status, detail, field, body)
        self.retry_after = retry_after


class ServerError(APIError):
    """5xx other than a busy 503: the server failed."""


class JobFailed(V3DError):
    """A job the client waited for failed; ``job`` is it, its ``message`` the server's reason."""

    def __init__(self, job: Job) -> None:
        self.job = job
        super().__init__(f"job {job.id} ({job.kind}) failed: {job.message}")


class JobTimeout(V3DError):
    """A job did not finish within the time the client was given to wait; ``job`` is it as last read."""

    def __init__(self, job: Job, timeout_s: float) -> None:
        self.job = job
        super().__init__(f"job {job.id} ({job.kind}) is still {job.state} after {timeout_s:g} s "
                         f"({job.stage or 'no stage'} {job.done}/{job.total})")


_BY_STATUS: dict[int, type[APIError]] = {400: BadRequest, 401: Unauthorized, 403: Forbidden, 404: NotFound,
                                         409: Conflict, 412: EditConflict, 413: TooLarge, 422: Invalid,
                                         428: PreconditionRequired, 429: Busy, 503: Busy}


def _words(body: Any, reason: str) -> tuple[str, Optional[str]]:
    """The server's sentence and the field it names, from an error body (``{"detail": str, "field"?}`` or FastAPI's
    ``{"detail": [{"loc", "msg"}, ...]}``).

    >>> _words({"detail": [{"loc": ["body", "box", 0], "msg": "Input should be finite"}]}, "")
    ('box.0: Input should be finite', 'box.0')
    >>> _words({"detail": "no such frame", "field": None}, "Not Found")
    ('no such frame', None)
    """
    if not isinstance(body, dict):
        return reason, None
    detail, field = body.get("detail"), body.get("field")
    if isinstance(detail, list):
        fields, lines = [], []
        for item in detail:
            loc = [str(p) for p in (item.get("loc") or []) if p not in ("body", "query", "path", "header")]
            name = ".".join(loc) or None
            if name:
                fields.append(name)
            lines.append(f"{name}: {item.get('msg')}" if name else str(item.get("msg")))
        return "; ".join(lines) or reason, field or (fields[0] if fields else None)
    return (str(detail) if detail is not None else reason), field


def error_for(status: int, body: Any, reason: str, retry_after: Optional[float] = None) -> APIError:
    """The :class:`APIError` of an answer of ``status`` with the JSON ``body`` (None when not JSON)."""
    detail, field = _words(body, reason)
    cls = _BY_STATUS.get(status, ServerError if status >= 500 else APIError)
    if cls is Busy:
        return Busy(status, detail, field, body, retry_after)
    if cls is EditConflict and not isinstance(body, dict):
        cls = APIError
    return cls(status, detail, field, body)
