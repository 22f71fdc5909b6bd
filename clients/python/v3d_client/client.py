"""The v3d client: one :class:`Client` per server, its methods one per thing a script does.

Every method speaks to one route of the server's REST API (recorded in :data:`ROUTES`, which the server's drift test
reads) and answers typed objects (``v3d_client.models``). What each method takes care of:

* **authentication**: an API token (``Authorization: Bearer``), or a name and password (a session: the client logs
  in at its first call and sends the session's CSRF token on every write);
* **the server's version**: read at the first call (``GET /api/health``); a server of another version raises
  :class:`~v3d_client.errors.VersionMismatch` saying which;
* **paging**: every list is an iterator over all its pages (the queue by its cursor, the others by offset);
* **conflict-safe edits**: an edit takes the object it was made against (a :class:`~v3d_client.models.Frame`,
  :class:`~v3d_client.models.View` or :class:`~v3d_client.models.System`) and sends its ``etag`` as ``If-Match``; a
  stale one raises :class:`~v3d_client.errors.EditConflict` holding the state now and the changes since;
* **a busy server**: 503 and 429 are sent again after their ``Retry-After`` (at most ``retries`` times, each wait at
  most ``max_wait_s``), then raise :class:`~v3d_client.errors.Busy`; both mean nothing was done;
* **uploads and downloads**: streamed from and to files, never whole in memory, with a progress callback;
* **jobs**: :meth:`Client.wait` polls a job until it is done, with a progress callback and a timeout;
* **a hostile or broken server**: an answer is read in pieces up to ``max_answer_bytes`` and within
  ``total_timeout_s`` (each read waits at most what is left of it), redirects are never followed, and an answer that is
  not what the route promises (not JSON, JSON of another shape) is refused: each raises its own
  :class:`~v3d_client.errors.BadAnswer` naming the server, the request and what it answered, never a traceback of
  httpx, json or pydantic.
"""
from __future__ import annotations

import functools
import inspect
import os
import tempfile
import time
import zipfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack
from datetime import datetime, timezone
from email.utils import parsedate_to_datetime
from pathlib import Path
from typing import IO, Any, Optional, TypeVar

import httpx
from pydantic import ValidationError

from v3d_client.errors import (
    AnswerTooLarge,
    AnswerTooSlow,
    BadAnswer,
    JobFailed,
    JobTimeout,
    NotJSON,
    Redirected,
    Unreachable,
    V3DError,
    VersionMismatch,
    WrongShape,
    error_for,
)
from v3d_client.models import (
    Annotator,
    Annotators,
    AuditEntry,
    AuditPage,
    Batch,
    BatchAccepted,
    BatchUndone,
    Comment,
    CommentPage,
    Decision,
    Doubt,
    Frame,
    FramePage,
    FrameRow,
    Game,
    Health,
    Job,
    JobPage,
    Me,
    Model,
    PredictionSource,
    PredictionSources,
    PredictionsRemoved,
    Release,
    ReleaseDiff,
    Releases,
    Review,
    Stats,
    System,
    SystemPage,
    SystemSummary,
    Token,
    TokenSummary,
    User,
    View,
)
from v3d_client.progress import BytesProgress, JobProgress
from v3d_client.version import __version__, mismatch

#: The routes this client speaks to, ``"METHOD /path"`` -> the model of its answer (None: no JSON answer, a file).
#: Filled by :func:`_route` as the methods are defined; the server's drift test compares it with its OpenAPI.
ROUTES: dict[str, Optional[type[Model]]] = {}

#: The server's routes this client does not speak to, ``"METHOD /path"`` -> why. The drift test fails on a route of
#: the server that is in neither :data:`ROUTES` nor here.
LEFT_OUT: dict[str, str] = {
    "GET /api/auth/demo": "the login page's question whether a demo account exists; a script logs in by token or "
                          "by name and password",
    "PUT /api/systems/{system_id}/presence": "the system page's heartbeat: a person's open tab, not a script's",
    "DELETE /api/systems/{system_id}/presence": "the end of the system page's heartbeat (a person closing the tab)",
    "POST /api/passes": "a review pass is the system page's walk through a frozen queue for a person deciding "
                        "with keys; a script walks the queue with Client.systems()",
    "GET /api/passes": "review passes are the page's (see POST /api/passes)",
    "GET /api/passes/{pass_id}": "review passes are the page's (see POST /api/passes)",
    "GET /api/passes/{pass_id}/place": "review passes are the page's (see POST /api/passes)",
    "POST /api/passes/{pass_id}/visits": "review passes are the page's (see POST /api/passes)",
    "POST /api/batches/{batch_id}/pass": "the system page's review pass over a batch's sample (see POST "
                                         "/api/passes); a script decides the sample with Client.decide",
    "GET /api/handoffs/mine": "the queue's 'To fix' and 'To re-review' counts for the person logged in; a script "
                              "asks Client.systems(status='needs_fix' or 'fixed', assignee=...)",
    "GET /api/systems/{system_id}/handoff": "the system page's hand-off banner; Client.decide answers the hand-off "
                                            "a decision made (Decision.returned_to, handoff)",
    "POST /api/assignments": "work assignment is the reviewers' queue-page action; no script task of this client "
                             "needs it yet (its answer would join v3d_client.models with it)",
    "GET /api/assignees": "the assignment menu's names (see POST /api/assignments)",
    "GET /api/frames/{frame_id}/pitch-lines": "the projected pitch the page redraws after an edit; Client.frame "
                                              "answers it already (Frame.pitch_lines)",
    "POST /api/frames/{frame_id}/calibration-preview": "the line editor's live preview while a point is dragged; it "
                                                        "stores nothing (Client.set_field_lines stores the lines)",
    "GET /api/exports/soccernet-v3d": "the export streamed within one request; Client.export runs the same export "
                                      "as a job (POST), byte for byte the same file, with progress while it is "
                                      "written and a download that does not hold a request open for the whole export",
    "GET /api/exports/cameras": "streamed within one request; Client.export('cameras', ...) runs it as a job",
    "GET /api/exports/yolo": "streamed within one request; Client.export('yolo', ...) runs it as a job",
    "GET /api/exports/coco": "streamed within one request; Client.export('coco', ...) runs it as a job",
    "GET /api/exports/issia-3d": "streamed within one request; Client.export('issia-3d', ...) runs it as a job",
    "POST /api/evaluations/monocular": "the statistics page's detector benchmark on an uploaded file; the paper's "
                                       "tables are `v3d evaluate` on the server's machine (docs/detectors.md)",
    "GET /api/evaluations/monocular": "the statistics page's benchmark of a stored source (see POST)",
    "GET /api/evaluations/boxes": "the statistics page's Table 1 figures (`v3d evaluate boxes`)",
    "GET /api/games/{game_id}/trajectory": "the ISSIA trajectory panel's data (a sequence's fitted 3D ball per "
                                           "frame); no script task of this client reads it yet",
    "GET /api/pitch-model": "the pitch's constant line classes the page draws with; nothing a script edits",
}

#: Environment variables of :meth:`Client.from_env` (the same names as the command line's ``v3d --server``).
URL_ENV, TOKEN_ENV = "V3D_URL", "V3D_TOKEN"
#: Bytes read or written at a time when streaming a file.
CHUNK_BYTES = 1 << 20
#: The longest answer a client reads into memory by default (bytes): a frame's image at the server's own bound
#: (``V3D_MAX_IMAGE_MB``, 256 MB) fits; a body past it is refused at its first byte past (:class:`AnswerTooLarge`).
MAX_ANSWER_BYTES = 256 << 20
#: The longest time one request may take by default, from its sending to its answer's last byte (s).
TOTAL_TIMEOUT_S = 120.0
#: How much of an answer a refusal quotes (characters).
QUOTED_CHARS = 80

_M = TypeVar("_M", bound=Model)
_F = TypeVar("_F", bound=Callable[..., Any])
Edited = Frame | View


def _route(*routes: str, answer: Optional[type[Model]] = None) -> Callable[[_F], _F]:
    """Record that the decorated method speaks to ``routes`` (``"METHOD /path"``), answering ``answer``."""
    def record(method: _F) -> _F:
        for r in routes:
            ROUTES[r] = answer
        return method
    return record


def _retry_after(response: httpx.Response) -> Optional[float]:
    """The answer's ``Retry-After`` in seconds (a number or an HTTP date), None when absent or unreadable."""
    value = response.headers.get("retry-after")
    if value is None:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:
        return max(0.0, (parsedate_to_datetime(value) - datetime.now(parsedate_to_datetime(value).tzinfo))
                   .total_seconds())
    except (TypeError, ValueError):
        return None


class _Reading:
    """A binary file read through :meth:`read`, calling ``progress(bytes read, size)`` as it goes (what httpx's
    multipart encoder reads an upload's file from, in pieces)."""

    def __init__(self, file: IO[bytes], size: int, progress: Optional[BytesProgress]) -> None:
        self._file, self._size, self._progress, self._done = file, size, progress, 0

    def read(self, n: int = -1) -> bytes:
        chunk = self._file.read(n)
        self._done += len(chunk)
        if self._progress is not None and chunk:
            self._progress(self._done, self._size)
        return chunk

    def fileno(self) -> int:
        return self._file.fileno()

    def tell(self) -> int:
        return self._file.tell()

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        if offset == 0 and whence == os.SEEK_SET:
            self._done = 0
        return self._file.seek(offset, whence)


def _quoted(text: Any) -> str:
    """``text`` as a refusal quotes it: at most :data:`QUOTED_CHARS` characters, every one printable."""
    shown = "".join(c if c.isprintable() else "?" for c in str(text)[:QUOTED_CHARS])
    return repr(shown + ("..." if len(str(text)) > QUOTED_CHARS else ""))


def _answered(client: "Client", exc: ValueError) -> BadAnswer:
    """The :class:`BadAnswer` of an answer that failed to parse (``exc`` from json or pydantic), naming the server,
    the request and what it answered (its status, type and first characters)."""
    method, path, response = client._last
    status = response.status_code if response is not None else None
    kind = response.headers.get("content-type", "no type") if response is not None else "no type"
    try:
        start = response.text if response is not None else ""
    except Exception:  # noqa: BLE001  # a streamed answer not read: nothing to quote
        start = ""
    said = f"{client.url} answered {method} {path} with {status} ({kind}) {_quoted(start)}"
    if isinstance(exc, ValidationError):
        first = exc.errors()[0] if exc.errors() else {"loc": (), "msg": str(exc)}
        where = ".".join(str(p) for p in first.get("loc", ())) or "the answer"
        return WrongShape(f"{said}: not the shape of its route ({where}: {first.get('msg')})", status)
    return NotJSON(f"{said}: not JSON ({exc})", status)


def _refusing_bad_answers(method: Callable[..., Any]) -> Callable[..., Any]:
    """``method`` of :class:`Client` with a ValueError of its answer's parsing raised as :func:`_answered`'s
    :class:`BadAnswer` (a generator's too, at each item)."""
    if inspect.isgeneratorfunction(method):
        @functools.wraps(method)
        def each(self: "Client", *args: Any, **kwargs: Any) -> Iterator[Any]:
            try:
                yield from method(self, *args, **kwargs)
            except V3DError:
                raise
            except ValueError as exc:
                raise _answered(self, exc) from None
        return each

    @functools.wraps(method)
    def call(self: "Client", *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except V3DError:
            raise
        except ValueError as exc:
            raise _answered(self, exc) from None
    return call


def zip_folder(folder: Path, target: Path) -> Path:
    """Write the files under ``folder`` into the zip ``target``, named relative to ``folder`` (``/``-separated),
    stored without compression (a dataset's images and Frames-v3.zip are compressed already). Returns ``target``.

    Raises:
        V3DError: ``folder`` holds no file.
    """
    files = sorted(p for p in folder.rglob("*") if p.is_file())
    if not files:
        raise V3DError(f"{folder} holds no file to upload")
    with zipfile.ZipFile(target, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for path in files:
            zf.write(path, path.relative_to(folder).as_posix())
    return target


class Client:
    """A connection to one v3d server.

    Args:
        url: the server, e.g. ``http://127.0.0.1:8000``.
        token: an API token (``v3d users add`` prints one; ``POST /api/users/{name}/tokens`` issues more).
        name, password: a user's name and password instead of a token (a browser session: the client logs in at
            its first call).
        timeout: seconds a request may take to connect, to send or to answer a piece (a download's whole may take
            longer).
        total_timeout_s: seconds a request may take in all, answer read (not a download's file): past it,
            :class:`AnswerTooSlow`.
        max_answer_bytes: the longest answer read into memory (JSON, a frame's image): past it,
            :class:`AnswerTooLarge`.
        retries: how many times a request answered 503 or 429 is sent again (its ``Retry-After`` waited first).
        max_wait_s: the longest ``Retry-After`` the client waits; a longer one raises :class:`Busy` at once.
        check_version: read the server's version at the first call and refuse one of another series.
        transport: an httpx transport (tests hand in one that speaks to an app directly).

    Raises:
        V3DError: neither a token nor a name and password.
    """

    def __init__(self, url: str, token: Optional[str] = None, *, name: Optional[str] = None,
                 password: Optional[str] = None, timeout: float = 60.0, retries: int = 5, max_wait_s: float = 30.0,
                 check_version: bool = True, transport: Optional[httpx.BaseTransport] = None,
                 total_timeout_s: float = TOTAL_TIMEOUT_S, max_answer_bytes: int = MAX_ANSWER_BYTES) -> None:
        if not token and not (name and password is not None):
            raise V3DError("give an API token (V3D_TOKEN) or a name and password")
        headers = {"User-Agent": f"v3d-client/{__version__}", "Accept": "application/json"}
        if token:
            headers["Authorization"] = f"Bearer {token}"
        self.url = url.rstrip("/")
        self._http = httpx.Client(base_url=self.url, headers=headers, timeout=timeout, transport=transport,
                                  follow_redirects=False)
        self._login = (name, password) if not token else None
        self._csrf: Optional[str] = None
        self.retries, self.max_wait_s = retries, max_wait_s
        self.timeout, self.total_timeout_s, self.max_answer_bytes = timeout, total_timeout_s, max_answer_bytes
        self._last: tuple[str, str, Optional[httpx.Response]] = ("", "", None)  # what :func:`_answered` names
        self._version_checked = not check_version
        self.server_version: Optional[str] = None

    @classmethod
    def from_env(cls, **options: Any) -> "Client":
        """A client of ``V3D_URL`` with the token ``V3D_TOKEN`` (``options``: the constructor's others).

        Raises:
            V3DError: ``V3D_URL`` or ``V3D_TOKEN`` is not set.
        """
        url, token = os.environ.get(URL_ENV), os.environ.get(TOKEN_ENV)
        if not url or not token:
            raise V3DError(f"set {URL_ENV} (the server, e.g. http://127.0.0.1:8000) and {TOKEN_ENV} (an API token)")
        return cls(url, token, **options)

    def close(self) -> None:
        """End the session (when logged in by name and password) and the connections."""
        try:
            if self._csrf is not None:
                self._send("POST", "/api/auth/logout")
        except V3DError:
            pass  # ending anyway: the session expires by itself
        finally:
            self._csrf = None
            self._http.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----- the wire -------------------------------------------------------------------------------------------------
    def _start(self) -> None:
        """Before the first call: the server's version, then the login of a name and password."""
        if not self._version_checked:
            self._version_checked = True
            health = self.health()
            self.server_version = health.version
            why = mismatch(health.version)
            if why is not None:
                raise VersionMismatch(f"{self.url}: {why}")
        if self._login is not None and self._csrf is None:
            name, password = self._login
            self._login = None
            me = Me.model_validate(self._send("POST", "/api/auth/login", json={"name": name, "password": password})
                                   .json())
            self._csrf = me.csrf_token or ""

    def _send(self, method: str, path: str, *, params: Optional[Mapping[str, Any]] = None, json: Any = None,
              etag: Optional[str] = None, upload: Optional[Callable[[ExitStack], dict[str, Any]]] = None,
              stream: bool = False) -> httpx.Response:
        """Send one request (again after a 503 or 429, within the bounds); the answer, or the error it is.

        ``upload`` makes the multipart body of an attempt (files opened on the given stack), so that an attempt sent
        again sends the file again from its start. A streamed answer must be closed by the caller."""
        if path not in ("/api/health", "/api/auth/login"):
            self._start()
        headers: dict[str, str] = {}
        if etag is not None:
            headers["If-Match"] = etag
        if self._csrf and method != "GET":
            headers["X-CSRF-Token"] = self._csrf
        query = {k: v for k, v in (params or {}).items() if v is not None}
        self._last = (method, path, None)
        for attempt in range(self.retries + 1):
            # an upload's body takes what its size takes (each piece bounded by ``timeout``): its answer's time is
            # counted from when the answer began
            deadline = time.monotonic() + self.total_timeout_s if upload is None else None
            with ExitStack() as files:
                parts = upload(files) if upload is not None else {}
                timeout = self._timeout_until(deadline, method, path) if deadline is not None else self.timeout
                request = self._http.build_request(method, path, params=query, json=json, headers=headers,
                                                   timeout=timeout, **parts)
                try:
                    response = self._http.send(request, stream=True)
                except httpx.TimeoutException as exc:
                    if deadline is not None and time.monotonic() >= deadline:
                        raise self._too_slow(method, path, None) from exc
                    raise Unreachable(f"{self.url}: {type(exc).__name__}: {exc}") from exc
                except httpx.TransportError as exc:
                    raise Unreachable(f"{self.url}: {type(exc).__name__}: {exc}") from exc
                if deadline is None:
                    deadline = time.monotonic() + self.total_timeout_s
                if 300 <= response.status_code < 400:
                    response.close()
                    where = response.headers.get("location")
                    raise Redirected(f"{self.url} answered {response.status_code} {response.reason_phrase} to "
                                     f"{method} {path}{f' (to {_quoted(where)})' if where else ''}: v3d never "
                                     f"follows a redirect; give the server's own URL", response.status_code)
                if response.status_code < 400 and stream:
                    self._last = (method, path, response)
                    return response
                if response.status_code < 400:
                    answer = self._read(response, deadline, method, path)
                    self._last = (method, path, answer)
                    return answer
                wait = _retry_after(response)
                busy = response.status_code in (429, 503)
                if busy and attempt < self.retries and (wait is None or wait <= self.max_wait_s):
                    response.close()
                    time.sleep(wait if wait is not None else min(self.max_wait_s, 0.5 * 2 ** attempt))
                    continue
                answer = self._read(response, deadline, method, path)
                try:
                    body = answer.json()
                except ValueError:
                    body = None
                raise error_for(response.status_code, body, response.reason_phrase, wait)
        raise AssertionError("unreachable: the last attempt returns or raises")

    def _timeout_until(self, deadline: float, method: str, path: str) -> httpx.Timeout:
        """Each wait of a request (to connect, to send a piece, to read a piece) at most ``timeout`` and at most what
        is left until ``deadline``."""
        left = deadline - time.monotonic()
        if left <= 0:
            raise self._too_slow(method, path, None)
        return httpx.Timeout(min(self.timeout, left), connect=min(self.timeout, left, 10.0))

    def _too_slow(self, method: str, path: str, status: Optional[int]) -> AnswerTooSlow:
        return AnswerTooSlow(f"{self.url} did not answer {method} {path} completely within {self.total_timeout_s:g} "
                             f"s{f' (status {status})' if status is not None else ''}: a body that never ends or "
                             f"comes a byte at a time; nothing more was read", status)

    def _read(self, response: httpx.Response, deadline: float, method: str, path: str) -> httpx.Response:
        """The streamed ``response`` read whole, in pieces, within ``deadline`` and ``max_answer_bytes`` (closed
        either way), as an answer held in memory.

        Raises:
            AnswerTooLarge, AnswerTooSlow: past either bound; Unreachable: the connection failed.
        """
        declared = response.headers.get("content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_answer_bytes:
            response.close()
            raise self._too_large(method, path, response.status_code, f"its Content-Length is {int(declared):,}")
        chunks, size = [], 0
        try:
            for chunk in response.iter_bytes():  # each piece as it arrives (a chunk size would wait to fill it)
                size += len(chunk)
                if size > self.max_answer_bytes:
                    raise self._too_large(method, path, response.status_code, "it sent more")
                chunks.append(chunk)
                if time.monotonic() >= deadline:
                    raise self._too_slow(method, path, response.status_code)
        except httpx.TimeoutException as exc:
            raise self._too_slow(method, path, response.status_code) from exc
        except httpx.DecodingError as exc:
            raise NotJSON(f"{self.url} answered {method} {path} with {response.status_code} in an encoding that "
                          f"does not decode ({response.headers.get('content-encoding')}: {exc})",
                          response.status_code) from None
        except httpx.TransportError as exc:
            raise Unreachable(f"{self.url}: {type(exc).__name__} while reading the answer to {method} {path}: "
                              f"{exc}") from exc
        finally:
            response.close()
        # the body as decoded: its headers without the encoding and length of the bytes that came
        headers = [(k, v) for k, v in response.headers.multi_items()
                   if k.lower() not in ("content-encoding", "content-length", "transfer-encoding")]
        return httpx.Response(response.status_code, headers=headers, content=b"".join(chunks),
                              request=response.request)

    def _too_large(self, method: str, path: str, status: int, said: str) -> AnswerTooLarge:
        return AnswerTooLarge(f"{self.url} answered {method} {path} (status {status}) with more than "
                              f"{self.max_answer_bytes:,} bytes ({said}), the most this client reads; nothing more "
                              f"was read", status)

    def _get(self, path: str, answer: type[_M], **params: Any) -> _M:
        return answer.model_validate(self._send("GET", path, params=params).json())

    def _pages(self, path: str, page: type[_M], params: Mapping[str, Any], limit: int) -> Iterator[Any]:
        """Every item of a list paged by offset (``next_offset``, or ``offset + len(items)`` below ``total``)."""
        offset = 0
        while True:
            got: Any = self._get(path, page, **{**params, "limit": limit, "offset": offset})  # a page: items, total
            items = got.items
            yield from items
            following = getattr(got, "next_offset", None)
            if following is None:
                following = offset + len(items) if offset + len(items) < got.total else None
            if following is None or not items:
                return
            offset = following

    # ----- who and what -------------------------------------------------------------------------------------------
    @_route("GET /api/health", answer=Health)
    def health(self) -> Health:
        """The server answers, and its version (public: no token needed)."""
        return self._get("/api/health", Health)

    @_route("POST /api/auth/login", "POST /api/auth/logout")
    @_route("GET /api/auth/me", answer=Me)
    def me(self) -> Me:
        """Who this client is (name, role, and whether by token or session)."""
        return self._get("/api/auth/me", Me)

    @_route("GET /api/games", answer=Game)
    def games(self) -> list[Game]:
        """Every game and its number of systems."""
        return [Game.model_validate(g) for g in self._send("GET", "/api/games").json()]

    # ----- systems --------------------------------------------------------------------------------------------------
    @_route("GET /api/systems", answer=SystemPage)
    def systems(self, *, status: Optional[str] = None, doubt: Optional[str] = None, game_id: Optional[int] = None,
                assignee: Optional[str] = None, jac_min: Optional[float] = None, jac_max: Optional[float] = None,
                error_min: Optional[float] = None, error_max: Optional[float] = None,
                sigma_min: Optional[float] = None, sigma_max: Optional[float] = None, camera: Optional[str] = None,
                ball_evidence: Optional[str] = None, sort: Optional[str] = None,
                page_size: int = 200) -> Iterator[SystemSummary]:
        """Every system of the queue that the filters keep, in the queue's order (``sort``), page after page by
        the queue's cursor (a system moved meanwhile is neither skipped nor repeated by the pages).

        Args:
            status: pending, accepted, rejected, needs_fix or fixed.
            doubt: a doubt kind (``mirrored_labels`` ...), ``any`` (a label-accusing doubt) or ``none``.
            game_id, assignee, jac_min, jac_max, error_min, error_max, sigma_min, sigma_max, camera, ball_evidence,
                sort: the queue's filters (``docs/api.md``); errors in pixels, JaC a fraction, the 3D ball's sigma in
                metres, ``ball_evidence`` a tier (vouched, unconfirmed, doubted, none).
            page_size: systems a request (at most 500).
        """
        params: dict[str, Any] = {"status": status, "doubt": doubt, "game_id": game_id, "assignee": assignee,
                                  "jac_min": jac_min, "jac_max": jac_max, "error_min": error_min,
                                  "error_max": error_max, "sigma_min": sigma_min, "sigma_max": sigma_max,
                                  "camera": camera, "ball_evidence": ball_evidence, "sort": sort,
                                  "limit": page_size}
        while True:
            page = self._get("/api/systems", SystemPage, **params)
            yield from page.items
            if not page.next_cursor or not page.items:
                return
            params["after"] = page.next_cursor

    @_route("GET /api/systems/{system_id}", answer=System)
    def system(self, system_id: int) -> System:
        """A system as its page shows it: views, doubts, triangulation; its ``etag`` and each view's."""
        return self._get(f"/api/systems/{int(system_id)}", System)

    @_route("POST /api/systems/{system_id}/review", answer=Decision)
    def decide(self, system: System, status: str, comment: str = "", *, assignee: Optional[str] = None) -> Decision:
        """Decide ``system`` (accepted, rejected, needs_fix; fixed by the person it was returned to), bound to the
        version read: :class:`EditConflict` when anything of it changed since (its ``changes_since`` says what).
        ``assignee``: needs_fix only, whom it is returned to (without it, the last editor of its labels or its
        assignee; with neither the server refuses it, naming ``assignee``). Reviewers (annotators: ``fixed`` only)."""
        body: dict[str, Any] = {"status": status, "comment": comment}
        if assignee is not None:
            body["assignee"] = assignee
        return Decision.model_validate(self._send("POST", f"/api/systems/{system.id}/review", etag=system.etag,
                                                  json=body).json())

    # ----- batches: the vouched accepted after a random sample -----------------------------------------------------
    @_route("POST /api/batches", answer=Batch)
    def create_batch(self, *, confidence: float = 0.95, max_wrong_share: float = 0.05,
                     **filters: Any) -> Batch:
        """Make a batch of the pending systems whose ball is vouched for that the queue's ``filters`` select
        (``game_id``, ``jac_min``, ``doubt``, ... as :meth:`systems` takes them), with the server's random sample of
        the zero-acceptance plan's size (59 for 95 % and 5 %) and the plan in words. Reviewers."""
        body = {"filter": {k: v for k, v in filters.items() if v is not None}, "confidence": confidence,
                "max_wrong_share": max_wrong_share}
        return Batch.model_validate(self._send("POST", "/api/batches", json=body).json())

    @_route("GET /api/batches/{batch_id}", answer=Batch)
    def batch(self, batch_id: int) -> Batch:
        """One batch, and while open what stops its accept now (``stops``: empty when it may be accepted)."""
        return self._get(f"/api/batches/{int(batch_id)}", Batch)

    @_route("POST /api/batches/{batch_id}/accept", answer=BatchAccepted)
    def accept_batch(self, batch_id: int) -> BatchAccepted:
        """Accept the batch's unsampled systems once a person accepted every sampled one and nothing else changed;
        :class:`Conflict` naming each system that stops it otherwise (a rejected or changed one refuses it for
        good). Reviewers."""
        return BatchAccepted.model_validate(self._send("POST", f"/api/batches/{int(batch_id)}/accept").json())

    @_route("POST /api/batches/{batch_id}/undo", answer=BatchUndone)
    def undo_batch(self, batch_id: int) -> BatchUndone:
        """Put the systems a batch accepted back to pending (those a person decided since are kept). Reviewers."""
        return BatchUndone.model_validate(self._send("POST", f"/api/batches/{int(batch_id)}/undo").json())

    # ----- frames and their edits ---------------------------------------------------------------------------------
    @_route("GET /api/frames", answer=FramePage)
    def frames(self, *, system_id: Optional[int] = None, game_id: Optional[int] = None,
               calibration: Optional[str] = None, admitted: Optional[bool] = None, sort: Optional[str] = None,
               page_size: int = 200) -> Iterator[FrameRow]:
        """Every frame the filters keep (``calibration``: calibrated, refused or none), page after page."""
        params = {"system_id": system_id, "game_id": game_id, "calibration": calibration,
                  "admitted": None if admitted is None else str(admitted).lower(), "sort": sort}
        return self._pages("/api/frames", FramePage, params, page_size)

    @_route("GET /api/frames/{frame_id}", answer=Frame)
    def frame(self, frame_id: int) -> Frame:
        """One frame as the system page draws it, with its ``etag``: the version an edit of it is bound to."""
        return self._get(f"/api/frames/{int(frame_id)}", Frame)

    @_route("GET /api/frames/{frame_id}/image")
    def frame_image(self, frame_id: int) -> bytes:
        """The frame's image (PNG or JPEG bytes)."""
        return self._send("GET", f"/api/frames/{int(frame_id)}/image").content

    def _edit(self, method: str, frame: Edited, tail: str, body: Any) -> System:
        return System.model_validate(self._send(method, f"/api/frames/{frame.frame_id}{tail}", etag=frame.etag,
                                                json=body).json())

    @_route("PATCH /api/frames/{frame_id}/ball", answer=System)
    def edit_ball(self, frame: Edited, *, box: Optional[list[float]] = None, point: Optional[list[float]] = None,
                  not_visible: bool = False) -> System:
        """Set the ball label of ``frame`` (as read: its ``etag`` is sent) to ``box`` ``[x1, y1, x2, y2]`` or
        ``point`` ``[x, y]`` (pixels of its image), or say the ball is not visible in it. Answers the recomputed
        system (its views carry their new ``etag``).

        Raises:
            EditConflict: the frame changed since it was read (``current`` is it now).
            Invalid: a box outside the image, not finite, or not exactly one of box, point and not_visible.
        """
        given = [box is not None, point is not None, not_visible]
        if sum(given) != 1:
            raise V3DError("give exactly one of box, point and not_visible")
        body: dict[str, Any] = ({"box": list(box)} if box is not None else {"point": list(point)}
                                if point is not None else {"box": None})
        return self._edit("PATCH", frame, "/ball", body)

    @_route("POST /api/frames/{frame_id}/exclusion", answer=System)
    def set_excluded(self, frame: Edited, excluded: bool = True) -> System:
        """Exclude the view ``frame`` from its system's triangulation (or restore it: ``excluded=False``)."""
        return self._edit("POST", frame, "/exclusion", {"excluded": excluded})

    @_route("POST /api/frames/{frame_id}/field-lines/mirror", answer=System)
    def mirror_field_lines(self, frame: Edited) -> System:
        """Apply the mirrored field-line labels to ``frame`` (409 when they bring its ball no closer)."""
        return self._edit("POST", frame, "/field-lines/mirror", None)

    @_route("PUT /api/frames/{frame_id}/field-lines", answer=System)
    def set_field_lines(self, frame: Edited, lines: Mapping[str, list[list[list[float]]]]) -> System:
        """Replace the field lines of ``frame`` (class -> polylines of ``[x, y]`` pixels); it is recalibrated."""
        return self._edit("PUT", frame, "/field-lines", {"lines": dict(lines)})

    @_route("POST /api/frames/{frame_id}/review", answer=Review)
    def review_view(self, frame: Edited, status: str, comment: str = "") -> Review:
        """Decide the ball label of the view ``frame`` (as read: its ``etag`` is sent): accepted, rejected or
        needs_fix. Answers the view's decision (read the frame again for its new ``etag``)."""
        return Review.model_validate(self._send("POST", f"/api/frames/{frame.frame_id}/review", etag=frame.etag,
                                                json={"status": status, "comment": comment}).json())

    @_route("POST /api/frames/{frame_id}/calibration-review", answer=Review)
    def review_calibration(self, frame: Edited, status: str, comment: str = "") -> Review:
        """Decide the calibration of the view ``frame`` (as read): accepted, rejected or needs_fix."""
        return Review.model_validate(self._send("POST", f"/api/frames/{frame.frame_id}/calibration-review",
                                                etag=frame.etag, json={"status": status, "comment": comment}).json())

    def apply_fix(self, doubt: Doubt, frame: Edited) -> System:
        """Send the one-key fix of ``doubt`` (its ``suggestion.request``: a snapped ball label, an exclusion or
        mirrored labels) on ``frame``, the doubt's view as read (its ``etag`` is sent).

        Raises:
            V3DError: the doubt has no fix, or ``frame`` is not its view.
            EditConflict: the view changed since it was read.
        """
        request = doubt.fix_request
        if request is None:
            raise V3DError(f"the {doubt.kind} doubt has no one-key fix")
        if doubt.frame_id != frame.frame_id:
            raise V3DError(f"the {doubt.kind} doubt is of frame {doubt.frame_id}, not {frame.frame_id}")
        prefix = f"/api/frames/{frame.frame_id}"
        if not str(request["path"]).startswith(prefix):
            raise V3DError(f"the fix's request {request['path']} is not an edit of frame {frame.frame_id}")
        return self._edit(str(request["method"]), frame, str(request["path"])[len(prefix):], request.get("body"))

    # ----- comments -------------------------------------------------------------------------------------------------
    @_route("GET /api/systems/{system_id}/comments", answer=CommentPage)
    def comments(self, system_id: int, page_size: int = 200) -> Iterator[Comment]:
        """Every comment of the system, oldest first (resolved ones too)."""
        return self._pages(f"/api/systems/{int(system_id)}/comments", CommentPage, {}, page_size)

    @_route("POST /api/systems/{system_id}/comments", answer=Comment)
    def add_comment(self, system_id: int, frame_id: int, text: str,
                    point: Optional[tuple[float, float]] = None) -> Comment:
        """Pin a comment on a view of the system (``point`` in its pixels, or the whole view)."""
        body = {"frame_id": frame_id, "text": text, "point": list(point) if point is not None else None}
        return Comment.model_validate(self._send("POST", f"/api/systems/{int(system_id)}/comments", json=body).json())

    @_route("POST /api/comments/{comment_id}/resolve", "POST /api/comments/{comment_id}/reopen", answer=Comment)
    def resolve_comment(self, comment_id: int, resolved: bool = True) -> Comment:
        """Mark a comment resolved (or open again: ``resolved=False``)."""
        action = "resolve" if resolved else "reopen"
        return Comment.model_validate(self._send("POST", f"/api/comments/{int(comment_id)}/{action}").json())

    # ----- jobs -----------------------------------------------------------------------------------------------------
    @_route("GET /api/jobs", answer=JobPage)
    def jobs(self, *, state: Optional[str] = None, kind: Optional[str] = None, page_size: int = 100) -> Iterator[Job]:
        """Every job, newest first (``state``: queued, running, done, failed; ``kind``: import, recompute, export)."""
        return self._pages("/api/jobs", JobPage, {"state": state, "kind": kind}, page_size)

    def job_page(self, *, state: Optional[str] = None, kind: Optional[str] = None, limit: int = 50,
                 offset: int = 0) -> JobPage:
        """One page of :meth:`jobs` (its ``total``: how many jobs in all)."""
        return self._get("/api/jobs", JobPage, state=state, kind=kind, limit=limit, offset=offset)

    @_route("GET /api/jobs/{job_id}", answer=Job)
    def job(self, job_id: int) -> Job:
        """One job: its state, progress, and when done its result (failed: ``message`` says why)."""
        return self._get(f"/api/jobs/{int(job_id)}", Job)

    def wait(self, job: Job | int, *, progress: Optional[JobProgress] = None, timeout_s: Optional[float] = None,
             poll_s: float = 0.5) -> Job:
        """Wait until ``job`` is done; the job then (its ``result``).

        Args:
            progress: called with the job at every reading (its ``stage``, ``done`` of ``total``).
            timeout_s: the longest wait (None: as long as it runs).
            poll_s: the longest pause between two readings (the first ones come sooner).

        Raises:
            JobFailed: the job failed (its ``message`` says why).
            JobTimeout: it was not done within ``timeout_s``.
        """
        job_id = job if isinstance(job, int) else job.id
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        pause = min(0.05, poll_s)
        while True:
            current = self.job(job_id)
            if progress is not None:
                progress(current)
            if current.state == "done":
                return current
            if current.state == "failed":
                raise JobFailed(current)
            if deadline is not None and time.monotonic() >= deadline:
                raise JobTimeout(current, timeout_s or 0.0)
            left = poll_s if deadline is None else max(0.0, deadline - time.monotonic())
            time.sleep(min(pause, left))
            pause = min(poll_s, pause * 2)

    @_route("GET /api/jobs/{job_id}/result")
    def download(self, job: Job | int, out: str | Path, *, progress: Optional[BytesProgress] = None) -> Path:
        """Stream the file a finished export job wrote into ``out`` (a file path; its folder must exist), reading it
        in pieces; ``progress(bytes, size)`` as it arrives. Nothing is left at ``out`` when the download fails.

        Raises:
            Conflict: the job is not a finished export.
            NotFound: its file is gone (kept ``V3D_EXPORT_KEEP_HOURS``).
        """
        job_id = job if isinstance(job, int) else job.id
        target = Path(out)
        response = self._send("GET", f"/api/jobs/{job_id}/result", stream=True)
        try:
            size = int(response.headers["content-length"]) if "content-length" in response.headers else None
            done = 0
            with open(target, "wb") as f:
                for chunk in response.iter_bytes(CHUNK_BYTES):
                    f.write(chunk)
                    done += len(chunk)
                    if progress is not None:
                        progress(done, size)
        except BaseException:
            target.unlink(missing_ok=True)
            raise
        finally:
            response.close()
        return target

    @_route("POST /api/recompute", answer=Job)
    def recompute(self) -> Job:
        """Queue a full recompute with the server's settings (admins); :meth:`wait` on it."""
        return Job.model_validate(self._send("POST", "/api/recompute").json())

    # ----- imports --------------------------------------------------------------------------------------------------
    @_route("POST /api/imports", answer=Job)
    def upload(self, path: str | Path, kind: str, *, merge: Optional[str] = None, source: Optional[str] = None,
               width: Optional[int] = None, height: Optional[int] = None, from_lines: bool = False,
               flip: Optional[list[str]] = None, progress: Optional[BytesProgress] = None) -> Job:
        """Upload a dataset and queue its import (admins); the queued job (:meth:`wait` on it).

        Args:
            path: a zip of the dataset, or a folder (zipped first into a temporary file, outside the working
                folder), or for ``kind="predictions"`` a CSV file (zipped alone).
            kind: soccernet-v3, soccernet-v3d, sn-calibration, issia or predictions.
            merge: games stored already: keep-newer or overwrite (without it such an import is a 409 naming them).
            source: predictions only: the detector's name (default: the file's stem).
            width, height, from_lines, flip: the format's options (``docs/datasets.md``).
            progress: ``progress(bytes sent, size)`` while the file uploads.

        Raises:
            Conflict: games stored already and no ``merge`` (``current["games"]`` names them).
            TooLarge, BadRequest, Invalid: the upload refused, the member or field named.
        """
        source_path = Path(path)
        fields = {"kind": kind, "merge": merge, "source": source, "width": width, "height": height,
                  "from_lines": "true" if from_lines else None, "flip": ",".join(flip) if flip else None}
        data = {k: str(v) for k, v in fields.items() if v is not None}
        with tempfile.TemporaryDirectory(prefix="v3d-upload-") as tmp:
            if source_path.is_dir():
                archive = zip_folder(source_path, Path(tmp) / f"{source_path.name}.zip")
            elif not zipfile.is_zipfile(source_path):
                archive = Path(tmp) / f"{source_path.stem}.zip"
                with zipfile.ZipFile(archive, "w", compression=zipfile.ZIP_DEFLATED) as zf:
                    zf.write(source_path, source_path.name)
            else:
                archive = source_path
            size = archive.stat().st_size

            def body(files: ExitStack) -> dict[str, Any]:
                f = files.enter_context(open(archive, "rb"))
                return {"files": {"file": (archive.name, _Reading(f, size, progress), "application/zip")},
                        "data": data}

            return Job.model_validate(self._send("POST", "/api/imports", upload=body).json())

    def import_server_path(self, path: str, kind: str, *, merge: Optional[str] = None,
                           source: Optional[str] = None) -> Job:
        """Queue the import of a dataset already on the server, ``path`` under its ``V3D_DATA_ROOT`` (admins)."""
        body = {k: v for k, v in {"kind": kind, "path": path, "merge": merge, "source": source}.items()
                if v is not None}
        return Job.model_validate(self._send("POST", "/api/imports", json=body).json())

    # ----- exports and releases -----------------------------------------------------------------------------------
    @_route("POST /api/exports/soccernet-v3d", "POST /api/exports/{export_format}", answer=Job)
    def start_export(self, export_format: str, *, include_all: bool = False, release: Optional[str] = None,
                     images: bool = True) -> Job:
        """Queue an export (admins): ``export_format`` soccernet-v3d, cameras, yolo, coco or issia-3d; of the
        accepted systems now, every system (``include_all``) or a release (byte for byte the same whenever asked).
        ``images`` (soccernet-v3d): each game's Frames-v3.zip."""
        body: dict[str, Any] = {"all": include_all, "release": release}
        if export_format == "soccernet-v3d":
            body["images"] = images
        return Job.model_validate(self._send("POST", f"/api/exports/{export_format}", json=body).json())

    def export(self, export_format: str, out: str | Path, *, include_all: bool = False, release: Optional[str] = None,
               images: bool = True, job_progress: Optional[JobProgress] = None,
               progress: Optional[BytesProgress] = None, timeout_s: Optional[float] = None) -> Job:
        """Export to the zip ``out``: queue the export (:meth:`start_export`), wait for it (:meth:`wait`), download
        its file (:meth:`download`). The finished job (its ``result``: the export's counts)."""
        job = self.wait(self.start_export(export_format, include_all=include_all, release=release, images=images),
                        progress=job_progress, timeout_s=timeout_s)
        self.download(job, out, progress=progress)
        return job

    @_route("POST /api/backups", answer=Job)
    def start_backup(self, *, local_files: bool = True) -> Job:
        """Queue a backup of the whole deployment (admins): every table in one snapshot and the stored files it
        names, in one zip with its manifest. ``local_files``: the images a command-line import or the demo read from
        the server's own folders too (false lists their folders in the manifest instead). The archive holds every
        password and token hash: keep it as a secret."""
        return Job.model_validate(self._send("POST", "/api/backups", json={"local_files": local_files}).json())

    def backup(self, out: str | Path, *, local_files: bool = True, job_progress: Optional[JobProgress] = None,
               progress: Optional[BytesProgress] = None, timeout_s: Optional[float] = None) -> Job:
        """Back the deployment up into the zip ``out``: queue the backup (:meth:`start_backup`), wait for it
        (:meth:`wait`), download its archive (:meth:`download`). The finished job (its ``result``: what the
        archive holds)."""
        job = self.wait(self.start_backup(local_files=local_files), progress=job_progress, timeout_s=timeout_s)
        self.download(job, out, progress=progress)
        return job

    @_route("GET /api/releases", answer=Releases)
    def releases(self) -> list[Release]:
        """Every release, oldest first."""
        return self._get("/api/releases", Releases).items

    @_route("GET /api/releases/{name}", answer=Release)
    def release(self, name: str) -> Release:
        """One release."""
        return self._get(f"/api/releases/{_segment(name)}", Release)

    @_route("POST /api/releases", answer=Release)
    def create_release(self, name: str, note: str = "") -> Release:
        """Make a release of the accepted systems as they are now (admins; :class:`Conflict` for a name taken)."""
        return Release.model_validate(self._send("POST", "/api/releases", json={"name": name, "note": note}).json())

    @_route("GET /api/releases/{a}/diff/{b}", answer=ReleaseDiff)
    def release_diff(self, a: str, b: str) -> ReleaseDiff:
        """What changed from release ``a`` to release ``b``."""
        return self._get(f"/api/releases/{_segment(a)}/diff/{_segment(b)}", ReleaseDiff)

    def release_diff_csv(self, a: str, b: str) -> str:
        """:meth:`release_diff` as the server's CSV."""
        return self._send("GET", f"/api/releases/{_segment(a)}/diff/{_segment(b)}", params={"format": "csv"}).text

    # ----- a detector's predictions -------------------------------------------------------------------------------
    def import_predictions(self, path: str | Path, source: Optional[str] = None, *,
                           progress: Optional[BytesProgress] = None) -> Job:
        """Upload a detector's predictions (a CSV ``league,season,match,image,x1,y1,x2,y2,score``, or a zip of YOLO
        or COCO files) as ``source`` and queue their import (admins): :meth:`upload` of kind ``predictions``."""
        return self.upload(path, "predictions", source=source, progress=progress)

    @_route("GET /api/predictions", answer=PredictionSources)
    def prediction_sources(self) -> list[PredictionSource]:
        """Every stored detector source: counts and the spread of its scores."""
        return self._get("/api/predictions", PredictionSources).items

    @_route("DELETE /api/predictions/{source}", answer=PredictionsRemoved)
    def remove_predictions(self, source: str) -> PredictionsRemoved:
        """Remove a source's predictions (and the doubts they made) (admins)."""
        return PredictionsRemoved.model_validate(self._send("DELETE", f"/api/predictions/{_segment(source)}").json())

    # ----- users ----------------------------------------------------------------------------------------------------
    @_route("GET /api/users", answer=User)
    def users(self) -> list[User]:
        """Every user by name (admins)."""
        return [User.model_validate(u) for u in self._send("GET", "/api/users").json()]

    @_route("POST /api/users", answer=Token)
    def add_user(self, name: str, role: str, password: Optional[str] = None) -> Token:
        """A new user of ``role`` (annotator, reviewer, admin) and its first API token, shown this once (admins)."""
        body = {"name": name, "role": role, "password": password}
        return Token.model_validate(self._send("POST", "/api/users", json=body).json())

    @_route("PATCH /api/users/{name}", answer=User)
    def update_user(self, name: str, *, role: Optional[str] = None, disabled: Optional[bool] = None) -> User:
        """Change a user's role, or disable or enable it (admins)."""
        body = {k: v for k, v in {"role": role, "disabled": disabled}.items() if v is not None}
        return User.model_validate(self._send("PATCH", f"/api/users/{_segment(name)}", json=body).json())

    @_route("GET /api/users/{name}/tokens", answer=TokenSummary)
    def tokens(self, name: str) -> list[TokenSummary]:
        """Every API token of the user (never the token itself) (admins)."""
        return [TokenSummary.model_validate(t) for t in self._send("GET", f"/api/users/{_segment(name)}/tokens").json()]

    @_route("POST /api/users/{name}/tokens", answer=Token)
    def issue_token(self, name: str, label: Optional[str] = None, expires_days: Optional[int] = None) -> Token:
        """Another API token for the user (admins)."""
        body = {"label": label, "expires_days": expires_days}
        return Token.model_validate(self._send("POST", f"/api/users/{_segment(name)}/tokens", json=body).json())

    @_route("DELETE /api/users/{name}/tokens/{token_id}", answer=TokenSummary)
    def revoke_token(self, name: str, token_id: int) -> TokenSummary:
        """Revoke one API token of the user: it stops working at once (admins)."""
        return TokenSummary.model_validate(
            self._send("DELETE", f"/api/users/{_segment(name)}/tokens/{int(token_id)}").json())

    # ----- the audit ------------------------------------------------------------------------------------------------
    @_route("GET /api/audit", answer=AuditPage)
    def audit(self, *, system_id: Optional[int] = None, frame_id: Optional[int] = None, user: Optional[str] = None,
              since: Optional[datetime] = None, until: Optional[datetime] = None,
              page_size: int = 200) -> Iterator[AuditEntry]:
        """Every audit entry, newest first, of a system, a frame or a user; with ``since`` and ``until`` (UTC when
        they name no offset), those written at or after ``since`` and before ``until`` (the server filters them)."""
        span = {name: (when if when.tzinfo is not None else when.replace(tzinfo=timezone.utc)).isoformat()
                for name, when in (("since", since), ("until", until)) if when is not None}
        return self._pages("/api/audit", AuditPage,
                           {"system_id": system_id, "frame_id": frame_id, "user": user, **span}, page_size)

    @_route("POST /api/audit/{entry_id}/revert", answer=System)
    def revert(self, entry: AuditEntry | int, *, force: bool = False) -> System:
        """Restore the entry's ``before`` (reviewers; :class:`Conflict` when its resource changed since, unless
        ``force``). Answers the recomputed system."""
        entry_id = entry if isinstance(entry, int) else entry.id
        return System.model_validate(self._send("POST", f"/api/audit/{entry_id}/revert",
                                                params={"force": "true" if force else None}).json())

    @_route("POST /api/audit/{entry_id}/undo", answer=System)
    def undo(self, entry: AuditEntry | int) -> System:
        """Undo the entry (an annotator their own, when nobody wrote the view since; reviewers any)."""
        entry_id = entry if isinstance(entry, int) else entry.id
        return System.model_validate(self._send("POST", f"/api/audit/{entry_id}/undo").json())

    # ----- statistics -----------------------------------------------------------------------------------------------
    @_route("GET /api/stats", answer=Stats)
    def stats(self) -> Stats:
        """The dataset at a glance: systems and images per kind and split, admission, distributions."""
        return self._get("/api/stats", Stats)

    @_route("GET /api/stats/annotators", answer=Annotators)
    def annotators(self, *, since: Optional[datetime] = None, until: Optional[datetime] = None) -> list[Annotator]:
        """Per person: edits, systems touched and decided, needs fix received, label distance, decisions (reviewers);
        ``since`` / ``until`` bound the entries' times."""
        params = {"since": since.isoformat() if since else None, "until": until.isoformat() if until else None}
        return self._get("/api/stats/annotators", Annotators, **params).items


def _segment(name: str) -> str:
    """``name`` as one path segment (``/`` and the rest escaped)."""
    from urllib.parse import quote

    return quote(name, safe="")


for _name, _method in list(vars(Client).items()):  # every public call: an answer that does not parse is a BadAnswer
    if not _name.startswith("_") and inspect.isfunction(_method):
        setattr(Client, _name, _refusing_bad_answers(_method))
