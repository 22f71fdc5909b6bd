"""Pydantic schemas of the REST API's requests: query parameters, request bodies, and the error answers.

Separate from the ORM models (``app.db.models``); only the enums are shared. Units: pixels of the
frame's own image (continuous coordinates, origin at the top-left corner), world metres (z down), JaC
as fractions in [0, 1]. The answers of the review views (the system view, the UI contract of
``docs/api.md``) are in ``app.api.view_schemas``; those of other routers beside them
(``audit_schemas``, ``job_schemas``, ``issia_schemas``).
"""
from __future__ import annotations

import functools
import re
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Annotated, Any, Literal, Optional, Union

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

from app.core.names import check_name
from app.db.models import BallEvidence, ReviewStatus
from app.db.types import DB_INT_MAX, DB_INT_MIN
from app.geometry.doubts import INFO_KINDS, LABEL_KINDS
from app.services.accounts.users import ASSIGNEE_ME
from app.services.curation.queue import (
    DEFAULT_SORT,
    FrameFilters,
    FrameSort,
    SystemFilters,
    SystemSort,
)

#: A coordinate of a request body: a JSON number (``true`` or ``"1"`` are refused naming the field, not
#: read as 1.0); NaN and infinity pass here so that the services refuse them with their message.
InCoord = Annotated[float, Strict()]
InPoint2 = tuple[InCoord, InCoord]
InBox = tuple[InCoord, InCoord, InCoord, InCoord]
#: The ``doubt`` filter of the queue: a doubt kind, ``any`` label-accusing doubt, or ``none``.
if TYPE_CHECKING:  # mypy cannot build a Literal from values computed at import
    DoubtFilter = str
else:
    DoubtFilter = Literal[LABEL_KINDS + INFO_KINDS + ("any", "none")]
#: Bounds of an integer compared with a stored one (ids, offsets): the id columns are ``INTEGER``, 32-bit signed
#: on PostgreSQL (SQLite's are 64-bit). A larger number would fail in the database or its driver (a 500:
#: "integer out of range", OverflowError; found by ``benchmarks/fuzz.py``); it is a 422 naming the parameter.
#: An id (or any integer compared with a stored one) in a path or query parameter or a body: the one id type of the
#: API (``app.api.deps.SystemIdPath`` and the other path parameters add their description to it; the system page's
#: address is read by :func:`db_id`).
DbInt = Annotated[int, Field(ge=DB_INT_MIN, le=DB_INT_MAX)]


def db_id(text: str) -> Optional[int]:
    """The id a path segment names when :data:`DbInt` holds it (decimal digits within the database's integers),
    else None (no row can have it).

    >>> db_id("42"), db_id("2147483647"), db_id("2147483648"), db_id("9000000000"), db_id("-1"), db_id("4x")
    (42, 2147483647, None, None, None, None)
    """
    if not (text.isascii() and text.isdigit()) or len(text) > len(str(DB_INT_MAX)):
        return None
    value = int(text)
    return value if DB_INT_MIN <= value <= DB_INT_MAX else None
#: Text in a path or query parameter compared with stored text: no NUL character (PostgreSQL's text cannot hold
#: one: a 500 there, found by ``benchmarks/fuzz.py`` in the audit log's ``user`` filter).
QueryText = Annotated[str, Field(pattern=r"^[^\x00]*$")]


#: The start of an ISO 8601 date (YYYY-MM-DD): what a time given to the API must begin with.
_ISO_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}")


def _iso_text(value: Any) -> Any:
    """Refuses text that is no ISO 8601 time before pydantic reads it: pydantic's lax mode would take ``-8`` or
    ``1700000000`` as seconds since 1970 (found by ``benchmarks/fuzz.py``: ``since=-8`` answered 200), where the
    OpenAPI document promises a ``date-time``. Raises ``ValueError`` (a 422 naming the field)."""
    if isinstance(value, str) and not _ISO_DATE.match(value):  # a query's value is text
        raise ValueError("not an ISO 8601 time: give YYYY-MM-DD, optionally THH:MM[:SS] and an offset (Z for UTC)")
    return value


def _utc_unless_said(when: datetime) -> datetime:
    """The time in UTC, one that names no offset read as UTC (the times the API answers are UTC). Raises
    ``ValueError`` (a 422 naming the field) for a time whose UTC falls outside the years 1-9999."""
    if when.utcoffset() is None:
        return when.replace(tzinfo=timezone.utc)
    try:
        return when.astimezone(timezone.utc)
    except OverflowError:
        raise ValueError("outside the years 1-9999 once in UTC") from None


#: A time of a query (the audit log's and the annotators' ``since`` / ``until``): ISO 8601 text only, UTC when it
#: names no offset.
UtcTime = Annotated[datetime, BeforeValidator(_iso_text), AfterValidator(_utc_unless_said)]


#: What text from a client may not hold, and why: NUL (PostgreSQL's text cannot hold it: a 500 there, found by
#: ``benchmarks/fuzz.py``), and a lone UTF-16 surrogate (JSON's ``"\\ud800"`` escape parses to one; it is no Unicode
#: text, so no database, log or UTF-8 answer can hold it: a 500 wherever it went).
UNSTORABLE_TEXT = re.compile("[\x00\ud800-\udfff]")


def unstorable_text_at(value: Any, where: str = "") -> Optional[tuple[str, str]]:
    """Where the first string in ``value`` (nested dicts, lists; keys included) holds a character of
    :data:`UNSTORABLE_TEXT`, and what it is: ``(path, "NUL (\\x00) characters")`` or ``(path, "a lone surrogate
    ...")``, the path like ``"lines.Goal left crossbar"`` (``""`` for ``value`` itself); None when there is none.

    >>> unstorable_text_at({"comment": "ok", "lines": {"a\\x00": []}})[0], unstorable_text_at(["ok"])
    ('lines', None)
    >>> unstorable_text_at({"filter": {"assignee": "x\\ud800"}})[0]
    'filter.assignee'
    """
    if isinstance(value, str):
        found = UNSTORABLE_TEXT.search(value)
        if found is None:
            return None
        what = "NUL (\\x00) characters" if found.group() == "\x00" else "a lone surrogate (\\ud800-\\udfff)"
        return where, what
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, item in items:
        inner = f"{where}.{key}" if where else str(key)
        bad_key = unstorable_text_at(key, where) if isinstance(key, str) else None
        if bad_key is not None:
            return bad_key
        found_inner = unstorable_text_at(item, inner)
        if found_inner is not None:
            return found_inner
    return None


Loc = tuple[Union[str, int], ...]


def boolean_for_number_at(value: Any, schema: dict[str, Any], defs: dict[str, Any], where: Loc = ()) -> Optional[Loc]:
    """Where in ``value`` (a request body as parsed from JSON) a boolean stands where ``schema`` (its JSON schema;
    ``defs``: the schema's ``$defs``) expects a number and no boolean, as a location (``("point", 0)``); None when
    nowhere.

    Pydantic's lax mode reads ``true`` as 1 (``point: [true, 1]`` was stored as ``[1.0, 1.0]``): every body
    refuses it before any coercion (:class:`_In`), naming where.

    >>> schema = {"properties": {"point": {"anyOf": [{"type": "array", "items": {"type": "number"}},
    ...                                              {"type": "null"}]}, "ok": {"type": "boolean"}}}
    >>> boolean_for_number_at({"point": [True, 1], "ok": True}, schema, {}), boolean_for_number_at({"ok": True},
    ...                                                                                            schema, {})
    (('point', 0), None)
    """
    ref = schema.get("$ref")
    if isinstance(ref, str):
        schema = defs.get(ref.rsplit("/", 1)[-1], {})
    options = schema.get("anyOf") or schema.get("oneOf") or [schema]
    if isinstance(value, bool):
        types = {o.get("type") for o in options}
        return where if types & {"number", "integer"} and "boolean" not in types else None
    for option in options:
        if "$ref" in option:
            option = defs.get(str(option["$ref"]).rsplit("/", 1)[-1], {})
        inner: Optional[dict[str, Any]]
        if isinstance(value, list):
            prefix, items = option.get("prefixItems") or [], option.get("items")
            for i, item in enumerate(value):
                inner = prefix[i] if i < len(prefix) else items if isinstance(items, dict) else None
                found = boolean_for_number_at(item, inner, defs, (*where, i)) if inner else None
                if found is not None:
                    return found
        elif isinstance(value, dict):
            properties, rest = option.get("properties") or {}, option.get("additionalProperties")
            for key, item in value.items():
                inner = properties.get(key) if key in properties else rest if isinstance(rest, dict) else None
                found = boolean_for_number_at(item, inner, defs, (*where, key)) if inner else None
                if found is not None:
                    return found
    return None


@functools.cache
def _body_schema(model: type[BaseModel]) -> dict[str, Any]:
    return model.model_json_schema()


def refuse_booleans_for_numbers(model: type[BaseModel], data: Any) -> None:
    """Refuse ``data`` when it holds a boolean in a place of ``model`` that expects a number
    (:func:`boolean_for_number_at`): the one rule for the numbers of every request body, before any coercion.

    Raises:
        pydantic.ValidationError: located where the boolean is (the API's 422 names ``["body", "point", 0]``).
    """
    schema = _body_schema(model)
    found = boolean_for_number_at(data, schema, schema.get("$defs", {}))
    if found is not None:
        error = PydanticCustomError("bool_for_number", "a number is expected, not a boolean")
        raise ValidationError.from_exception_data(model.__name__, [InitErrorDetails(type=error, loc=found,
                                                                                    input=True)])


def readable_name(max_length: int, what: str = "a name") -> AfterValidator:
    """The validator of a body's name people read (a release's, a user's): ``app.core.names.check_name`` (no
    control or format character, not dots alone; the NFC form is what the route receives), a 422 naming the field."""
    return AfterValidator(functools.partial(_readable, max_length=max_length, what=what))


def _readable(value: str, *, max_length: int, what: str) -> str:
    return check_name(value, "name", max_length=max_length, what=what)  # an InvalidInputError is a ValueError


class _In(BaseModel):
    """Request bodies reject unknown fields, so a misspelt field is an error, not a no-op, text that cannot be
    stored anywhere (:data:`UNSTORABLE_TEXT`: NUL, lone surrogates), and a boolean where a number is expected
    (:func:`refuse_booleans_for_numbers`), naming where it is, before any coercion."""

    model_config = ConfigDict(extra="forbid")

    @model_validator(mode="before")
    @classmethod
    def _only_storable_text(cls, data: Any) -> Any:
        found = unstorable_text_at(data)
        if found is not None:
            where, what = found
            raise ValueError(f"{where or 'body'}: text must not contain {what}")
        refuse_booleans_for_numbers(cls, data)
        return data


# ----- query parameters ----------------------------------------------------------------------------
class QueueQuery(BaseModel):
    """Filters and order of the review queue (``GET /api/systems``; ``GET /api/systems/{id}`` takes
    them too, so that ``prev_id`` / ``next_id`` follow the queue the reviewer came from).

    Unknown query parameters are ignored (a page may forward its own state), unlike unknown fields
    of request bodies; numbers must be finite."""

    model_config = ConfigDict(allow_inf_nan=False)

    game_id: Optional[DbInt] = Field(None, description="Only this game's systems.")
    status: Optional[ReviewStatus] = Field(None, description="Only systems with this review status.")
    jac_min: Optional[float] = Field(None, ge=0.0, le=1.0, description="Lowest JaC@0.5% of the admitted views >= this.")
    jac_max: Optional[float] = Field(None, ge=0.0, le=1.0, description="Lowest JaC@0.5% of the admitted views <= this.")
    error_min: Optional[float] = Field(None, ge=0.0, description="Worst reprojection error (px) >= this.")
    error_max: Optional[float] = Field(None, ge=0.0, description="Worst reprojection error (px) <= this.")
    sigma_min: Optional[float] = Field(None, ge=0.0, description="The 3D ball's sigma (m) >= this (systems with a "
                                       "ball and its sigma only).")
    sigma_max: Optional[float] = Field(None, ge=0.0, description="The 3D ball's sigma (m) <= this (systems with a "
                                       "ball and its sigma only).")
    doubt: Optional[DoubtFilter] = Field(
        None, description="Only systems with a doubt of this kind; 'any': with a label-accusing doubt; "
        "'none': without one.")
    assignee: Optional[QueryText] = Field(
        None, min_length=1, max_length=100,
        description="Only systems assigned to this user (a name), 'me' (the caller's), or 'none' (unassigned ones); "
        "an unknown name matches nothing, as a user with none assigned does.")
    camera: Optional[Literal["rig_assisted", "player_assisted"]] = Field(
        None, description="Only systems with a view whose camera was placed so (a calibration flag: at a rig "
        "position, by its players).")
    ball_evidence: Optional[BallEvidence] = Field(
        None, description="Only systems whose 3D ball is in this tier: vouched (evidence beside its two rays agrees, "
        "no label doubt), unconfirmed (nothing else checks it), doubted (a label doubt names one of its views), none "
        "(no 3D ball).")
    sort: SystemSort = Field(DEFAULT_SORT, description="Order; a leading '-' means descending. Missing values last.")

    def filters(self, me: Optional[str] = None) -> SystemFilters:
        """The service-level filters; ``me``: the caller's name, which ``assignee=me`` stands for (without it,
        ``assignee=me`` filters nothing out)."""
        assignee = self.assignee
        if assignee == ASSIGNEE_ME:
            assignee = me
        return SystemFilters(game_id=self.game_id, status=self.status, jac_min=self.jac_min,
                             jac_max=self.jac_max, error_min=self.error_min, error_max=self.error_max,
                             sigma_min=self.sigma_min, sigma_max=self.sigma_max,
                             doubt=self.doubt, assignee=assignee, camera=self.camera,
                             ball_evidence=self.ball_evidence)

    @model_validator(mode="after")
    def _ranges(self) -> "QueueQuery":
        for lo, hi in (("jac_min", "jac_max"), ("error_min", "error_max"), ("sigma_min", "sigma_max")):
            a, b = getattr(self, lo), getattr(self, hi)
            if a is not None and b is not None and a > b:
                raise ValueError(f"{lo} ({a}) is larger than {hi} ({b})")
        return self


class SystemListQuery(QueueQuery):
    """:class:`QueueQuery` and the page."""

    limit: int = Field(50, ge=1, le=500)
    offset: int = Field(0, ge=0, le=DB_INT_MAX, description="Rows to skip (from `after`'s row when given).")
    after: Optional[str] = Field(None, max_length=4096, description="A page's next_cursor: the rows right after it.")
    before: Optional[str] = Field(None, max_length=4096, description="A page's prev_cursor: the rows right before it.")


class FrameListQuery(BaseModel):
    """Filters, order and page of ``GET /api/frames`` (numbers finite)."""

    model_config = ConfigDict(allow_inf_nan=False)

    game_id: Optional[DbInt] = None
    system_id: Optional[DbInt] = None
    calibration: Optional[Literal["calibrated", "refused", "none"]] = Field(
        None, description="Calibration status; 'none' for frames never calibrated.")
    admitted: Optional[bool] = Field(None, description="Admitted into their system's triangulation.")
    jac_min: Optional[float] = Field(None, ge=0.0, le=1.0, description="JaC@0.5% >= this.")
    jac_max: Optional[float] = Field(None, ge=0.0, le=1.0, description="JaC@0.5% <= this.")
    error_min: Optional[float] = Field(None, ge=0.0, description="Reprojection error (px) >= this.")
    error_max: Optional[float] = Field(None, ge=0.0, description="Reprojection error (px) <= this.")
    sort: FrameSort = Field("name", description="Order; a leading '-' means descending. Missing values last.")
    limit: int = Field(50, ge=1, le=500)
    offset: int = Field(0, ge=0, le=DB_INT_MAX)

    def filters(self) -> FrameFilters:
        """The service-level filters."""
        return FrameFilters(game_id=self.game_id, system_id=self.system_id, calibration=self.calibration,
                            admitted=self.admitted, jac_min=self.jac_min, jac_max=self.jac_max,
                            error_min=self.error_min, error_max=self.error_max)


# ----- request bodies ------------------------------------------------------------------------------
class BallEdit(_In):
    """A new ball label: exactly one of ``box`` and ``point``. ``{"box": null}`` (or
    ``{"point": null}``) removes the label: the ball is not visible in this view."""

    box: Optional[InBox] = Field(None, description="[x1, y1, x2, y2] px; finite, x1 < x2, y1 < y2, not entirely "
                                                   "outside the image.")
    point: Optional[InPoint2] = Field(None, description="[x, y] px inside the image (point-only datasets).")
    provenance: Optional[dict[str, Any]] = Field(
        None, description="Only for a label made from a doubt's suggestion (the fix key sends what the doubt's "
                          "`suggestion.request` says): {doubt, code, from_views}. Such a label joins no triangulation "
                          "until a person places it; an edit without provenance (drawn, moved, confirmed) clears it.")

    @model_validator(mode="after")
    def _one_of(self) -> "BallEdit":
        given = self.model_fields_set & {"box", "point"}
        if len(given) != 1:
            raise ValueError("give exactly one of 'box' and 'point' (null removes the label)")
        return self


#: Bounds of an edited line set (SoccerNet annotations hold a few points per line): the calibration of
#: an edit runs in the request.
MAX_POLYLINES_PER_CLASS = 100
MAX_POLYLINE_POINTS = 1000


class FieldLinesIn(_In):
    """A frame's complete field lines, SoccerNet class -> polylines of [x, y] px (finite, at most 5 % of the
    image's size outside it: ``app.datasets.labels.check_line_points``): the body of a calibration preview."""

    lines: dict[str, list[Annotated[list[InPoint2], Field(max_length=MAX_POLYLINE_POINTS)]]] = Field(
        max_length=64, description="At most 64 classes, 100 polylines per class and 1000 points per polyline.")

    @model_validator(mode="after")
    def _bounded(self) -> "FieldLinesIn":
        for name, polylines in self.lines.items():
            if len(polylines) > MAX_POLYLINES_PER_CLASS:
                raise ValueError(f"lines[{name!r}]: more than {MAX_POLYLINES_PER_CLASS} polylines")
        return self


class FieldLinesEdit(FieldLinesIn):
    """The frame's complete new field lines (as :class:`FieldLinesIn`), and the audit entry the write undoes."""

    undo_of: Optional[DbInt] = Field(None, description=(
        "This write undoes audit entry `undo_of` (a page's undo or redo of its own edit): a write of this frame's "
        "field lines whose `before` lines are exactly `lines` (else 422 naming `undo_of`). Audited as "
        "`field_lines.replace` with `reverts_id` = `undo_of`."))


class ReviewIn(_In):
    """A review decision."""

    status: ReviewStatus
    comment: str = Field("", max_length=4000)


class ExclusionIn(_In):
    """Exclude a view from its system's triangulation (true) or restore it (false)."""

    excluded: bool = Field(strict=True, description="true: exclude the view; false: restore it.")


# ----- responses -----------------------------------------------------------------------------------
class ErrorOut(BaseModel):
    """A domain error: 404 (the message names the missing id or file), 400 (a dataset that cannot be
    imported) or 422 (invalid input; ``field`` names it when known)."""

    detail: str
    field: Optional[str] = None


class InvalidOut(BaseModel):
    """A 422: invalid input named by the services (``detail`` a sentence, ``field`` the field), or
    FastAPI's request validation (``detail`` a list of ``{loc, msg, type}``, ``loc`` naming the field;
    a body that is not JSON answers ``loc: ["body"]``, ``app.api.errors``)."""

    detail: Union[str, list[dict[str, Any]]]
    field: Optional[str] = None


#: OpenAPI ``responses`` of routes that look a row up by id.
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorOut, "description": "No row has this id (the message names it)."}}
#: OpenAPI ``responses`` of routes that store input the services validate.
INVALID: dict[int | str, dict[str, Any]] = {
    422: {"model": InvalidOut, "description": "Invalid input: `{detail, field}` from the services, or "
                                              "FastAPI's `{detail: [{loc, msg, type}]}` for a malformed body."}}


class HealthOut(BaseModel):
    """The liveness answer, and the server's version (a client refuses a server of another series by it)."""

    status: str
    version: str = Field(description="The server's version (v3d's, and its client package's).")
