"""``/api/frames``: the frame list, frame images, and the reviewer's edits of one frame.

Edits answer the recomputed system view: the frame's calibration (after new field lines), the
system's triangulation, reprojections and optimised boxes. The edit, its recomputation and its audit
entry are committed together or not at all (``app.services.curation.editing``). Every edit is a conditional
write (``app.api.conditional``): it takes ``If-Match`` with the frame's ETag (412 when stale, 428 when
a token sends none) and answers the frame's new ETag in its ``ETag`` header.
"""
from __future__ import annotations

import contextlib
import re
import threading
from typing import Annotated, Any, Callable, Iterator, Literal

from fastapi import APIRouter, Depends, Header, HTTPException, Query, Response
from fastapi.responses import StreamingResponse
from sqlalchemy.orm import Session

from app.api.answers import json_answer
from app.api.auth import AnnotatorDep, PrincipalDep, require_role
from app.api.conditional import PRECONDITIONS, IfMatchDep, with_etag
from app.api.deps import EditDep, FrameDep, FrameIdPath, SessionDep, SettingsDep, ShareDep
from app.api.schemas import (
    INVALID,
    NOT_FOUND,
    BallEdit,
    ErrorOut,
    ExclusionIn,
    FieldLinesEdit,
    FieldLinesIn,
    FrameListQuery,
    QueueQuery,
    ReviewIn,
)
from app.api.share import SHARE_SPENT
from app.api.view_schemas import (
    CalibrationPreviewOut,
    FrameOut,
    FramePageOut,
    FrameView,
    PitchLinesOut,
    ReviewOut,
    SystemView,
    calibrated_camera,
    projected_pitch_of,
)
from app.db.models import Frame
from app.services.audit import log as audit
from app.services.curation import decisions, editing, queue, writing
from app.services.curation.calibration_preview import preview_calibration
from app.services.curation.system_page import load_frame, pitch_lines_key, system_page
from app.services.curation.versions import expected_versions, frame_etag
from app.services.curation.writing import EditContext
from app.services.images import serving as images
from app.services.storage.datasets import DatasetFiles

#: The header naming the audit entry of a write (what a later undo names).
AUDIT_ENTRY_HEADER = audit.AUDIT_ENTRY_HEADER
#: OpenAPI ``responses`` of the frame's edits.
EDIT_RESPONSES = {**NOT_FOUND, **INVALID, **PRECONDITIONS}
#: The mirror guard: the mirrored calibration would bring the view's ball label no closer to the others' 3D ball.
MIRROR_REFUSED: dict[int | str, dict[str, Any]] = {
    409: {"model": ErrorOut, "description": "Not applied: with the mirrored calibration the view's ball label comes no "
                                            "closer to the ball the other views agree on (the message gives both "
                                            "distances); nothing changed."}}

#: Frame edits (ball, field lines, mirror, exclusion, per-view review) need the annotator role.
router = APIRouter(prefix="/frames", tags=["frames"], dependencies=[Depends(require_role("annotator"))])

#: Served images are inert: the browser takes the checked type as it is and runs nothing from them.
IMAGE_SECURITY_HEADERS = {"X-Content-Type-Options": "nosniff", "Content-Security-Policy": "sandbox"}
#: Frame images never change under their id; the ETag covers a re-import from other files.
IMAGE_CACHE_CONTROL = "private, max-age=86400"


def etag_matches(if_none_match: str | None, etag: str) -> bool:
    """True when an ``If-None-Match`` header names ``etag`` (weak comparison, ``*`` matches all).

    >>> etag_matches('W/"ab-1", "cd-2"', '"cd-2"'), etag_matches('"ab-1"', '"cd-2"'), etag_matches("*", '"x"')
    (True, False, True)
    """
    if not if_none_match:
        return False
    tags = {t.strip().removeprefix("W/") for t in if_none_match.split(",")}
    return "*" in tags or etag.removeprefix("W/") in tags


def byte_range(header: str, size: int) -> tuple[int, int] | Literal["unsatisfiable"] | None:
    """The one byte range a ``Range`` header asks of ``size`` bytes, as (start, end exclusive); ``"unsatisfiable"``
    when it starts beyond the end; None when the header is not one ``bytes`` range (then the whole is sent, as RFC 9110
    allows).

    >>> byte_range("bytes=0-99", 1000), byte_range("bytes=900-", 1000), byte_range("bytes=-10", 1000)
    ((0, 100), (900, 1000), (990, 1000))
    >>> byte_range("bytes=1000-", 1000), byte_range("bytes=0-1,5-9", 1000), byte_range("items=0-1", 1000)
    ('unsatisfiable', None, None)
    >>> byte_range("bytes=\u00b2-", 1000), byte_range("bytes=9-2", 1000), byte_range("bytes=-", 1000)
    (None, None, None)
    """
    unit, _, spec = header.partition("=")
    first, dash, last = spec.strip().partition("-")
    digits = re.compile(r"[0-9]{1,19}")  # ASCII digits only (str.isdigit takes a superscript, int refuses it)
    if (unit.strip().lower() != "bytes" or not dash or (first and not digits.fullmatch(first))
            or (last and not digits.fullmatch(last)) or not (first or last)):
        return None
    if not first:  # the last N bytes
        n = int(last)
        return (max(0, size - n), size) if n > 0 else "unsatisfiable"
    start = int(first)
    if last and int(last) < start:
        return None  # not a valid range: ignored
    if start >= size:
        return "unsatisfiable"
    return start, min(size, int(last) + 1) if last else size


@router.get("", response_model=FramePageOut)
def list_frames(session: SessionDep, query: Annotated[FrameListQuery, Query()]) -> FramePageOut:
    """One page of frames, filtered by calibration status, admission, JaC@0.5% and error ranges."""
    page = queue.list_frames(session, query.filters(), query.sort, query.limit, query.offset)
    return FramePageOut(items=[FrameOut.of(f) for f in page.items], total=page.total, limit=query.limit,
                        offset=query.offset)


@router.get("/{frame_id}", response_model=FrameView, responses=NOT_FOUND)
def read_frame(session: SessionDep, frame: FrameDep, response: Response, _: PrincipalDep) -> FrameView:
    """The frame as the system view draws it (ball label, field lines, calibration, review, reprojection)
    with its ``system_id``; the ``ETag`` header (and ``etag`` field) is the version of what people edit on
    it, unchanged when a sibling view's edit recomputes it."""
    out = FrameView.of_frame(load_frame(session, frame.id))
    with_etag(response, out.etag)
    return out


#: A view's projected pitch, asked at the address of its version (its ``camera`` key): the same address always
#: answers the same lines, so the browser keeps them without asking again.
PITCH_LINES_KEPT = "private, max-age=31536000, immutable"


@router.get("/{frame_id}/pitch-lines", response_model=PitchLinesOut, responses={
    **NOT_FOUND, 304: {"description": "Not modified (If-None-Match names the current ETag)."}})
def read_pitch_lines(session: SessionDep, frame: FrameDep, response: Response, _: PrincipalDep,
                     camera: Annotated[str | None, Query(max_length=64, description=(
                         "The version named by the view's pitch_lines_url; when it is the current one the answer "
                         "may be kept for good (Cache-Control immutable), else it must be asked again."))] = None,
                     if_none_match: Annotated[str | None, Header()] = None) -> Response | PitchLinesOut:
    """The pitch model projected by the frame's current camera and clipped to its image (px), with an ``ETag``
    (its version: camera and image size). Asked once per calibration: the system view names it in each view's
    ``pitch_lines_url`` instead of sending the lines with every answer."""
    loaded = load_frame(session, frame.id)
    key = pitch_lines_key(calibrated_camera(loaded), loaded.width, loaded.height)
    etag = f'"pitch-{key or "none"}"'
    headers = {"ETag": etag, "Cache-Control": PITCH_LINES_KEPT if camera is not None and camera == key
               else "private, no-cache"}
    if etag_matches(if_none_match, etag):
        return Response(status_code=304, headers=headers)
    response.headers.update(headers)
    return PitchLinesOut(frame_id=loaded.id, camera=key, lines=projected_pitch_of(loaded))


def name_entry(edit: EditContext, response: Response) -> None:
    """Answer the id of the audit entry the write just committed (``edit.entry_id``) in ``X-V3D-Audit-Entry`` (what
    the page's undo names, ``POST /api/audit/{id}/undo``)."""
    if edit.entry_id is not None:
        response.headers[AUDIT_ENTRY_HEADER] = str(edit.entry_id)


def _edited(session: Session, response: Response, query: QueueQuery, me: str, edit: EditContext,
            write: Callable[[], Frame]) -> Response:
    """Run ``write`` (an edit by ``me``, whom ``assignee=me`` names, in the context ``edit``, answering the frame it
    edited) and answer the recomputed system view (the frame's system as the edit committed it), its new ETag and
    its audit entry in the header (serialised here: ``app.api.answers``)."""
    frame = write()
    name_entry(edit, response)
    with_etag(response, frame_etag(frame))
    return json_answer(SystemView.of(system_page(session, frame.system_id, query.filters(me=me), query.sort)),
                       response)


@router.get(
    "/{frame_id}/image",
    response_class=StreamingResponse,
    responses={
        200: {"content": {"image/png": {}, "image/jpeg": {}}, "description": "The image bytes."},
        206: {"description": "The byte range asked (Range: bytes=a-b), with Content-Range."},
        304: {"description": "Not modified (If-None-Match names the current ETag)."},
        416: {"description": "The range starts beyond the image's end (Content-Range: bytes */size)."},
        404: {"model": ErrorOut, "description": "No such frame, or it has no image (or none that is a PNG or JPEG "
                                                "inside its dataset's folder): draw a blank canvas of its size."},
    },
)
def frame_image(frame: FrameDep, settings: SettingsDep,
                if_none_match: Annotated[str | None, Header()] = None,
                range_: Annotated[str | None, Header(alias="range")] = None,
                if_range: Annotated[str | None, Header()] = None) -> Response:
    """The frame's image, streamed from its zip member (never extracted) or file, wherever the store keeps it, with an
    ``ETag``; one byte range of it (``Range: bytes=a-b``, 206 with ``Content-Range``; 416 beyond its end) unless
    ``If-Range`` names another version.

    Its media type is ``image/png`` or ``image/jpeg`` as read from the image's header (never from its
    name; anything else is a 404), with ``X-Content-Type-Options: nosniff`` and
    ``Content-Security-Policy: sandbox``, so that no imported file can run in this origin."""
    image = images.frame_image(frame, settings.max_image_pixels, DatasetFiles.from_settings(settings))
    headers = {"ETag": image.etag, "Cache-Control": IMAGE_CACHE_CONTROL, **IMAGE_SECURITY_HEADERS}
    if etag_matches(if_none_match, image.etag):
        return Response(status_code=304, headers=headers)
    headers["Accept-Ranges"] = "bytes"
    wanted = byte_range(range_, image.size) if range_ and (if_range is None or if_range == image.etag) else None
    if wanted == "unsatisfiable":
        return Response(status_code=416, headers={**headers, "Content-Range": f"bytes */{image.size}"})
    if isinstance(wanted, tuple):
        start, end = wanted
        headers.update({"Content-Length": str(end - start), "Content-Range": f"bytes {start}-{end - 1}/{image.size}"})
        return StreamingResponse(image.chunks(start, end), status_code=206, media_type=image.media_type,
                                 headers=headers)
    headers["Content-Length"] = str(image.size)
    return StreamingResponse(image.chunks(), media_type=image.media_type, headers=headers)


@router.patch("/{frame_id}/ball", response_model=SystemView, responses=EDIT_RESPONSES)
def edit_ball(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, if_match: IfMatchDep,
              frame_id: FrameIdPath, body: BallEdit, query: Annotated[QueueQuery, Query()],
              response: Response, edit: EditDep) -> Response:
    """Set the frame's ball box or point (or remove it with null) and answer the recomputed system view.

    422 naming ``box`` or ``point``: non-finite numbers, x2 <= x1 or y2 <= y1, a box entirely outside
    the image, a point outside it; ``provenance`` of another shape; nothing is stored then. A label sent with
    a ``provenance`` (a doubt's suggestion) is stored as suggested: it makes no 3D ball until a person places it.
    """
    return _edited(session, response, query, principal.name, edit, lambda: editing.update_ball_label(
        session, frame_id, box=body.box, point=body.point, provenance=body.provenance, settings=settings,
        actor=principal.name, expected=expected_versions(if_match, "frame", frame_id), edit=edit))


@router.put("/{frame_id}/field-lines", response_model=SystemView, responses=EDIT_RESPONSES)
def replace_field_lines(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, if_match: IfMatchDep,
                        frame_id: FrameIdPath, body: FieldLinesEdit, query: Annotated[QueueQuery, Query()],
                        response: Response, edit: EditDep) -> Response:
    """Replace the frame's field lines, recalibrate it, and answer the recomputed system view, with the
    id of the write's audit entry in ``X-V3D-Audit-Entry`` (what a later ``undo_of`` names).

    422 naming ``lines`` (and the class and polyline): an unknown class, an empty polyline, NaN or
    infinity; naming ``undo_of``: not a field-line write of this frame whose lines before were ``lines``;
    nothing is stored then.
    """
    return _edited(session, response, query, principal.name, edit, lambda: editing.replace_field_lines(
        session, frame_id, body.lines, settings=settings, actor=principal.name,
        expected=expected_versions(if_match, "frame", frame_id), undo_of=body.undo_of, edit=edit))


#: The calibration previews being computed in this process, by (user, frame): one at a time each.
_PREVIEWS: set[tuple[str, int]] = set()
_PREVIEWS_LOCK = threading.Lock()
PREVIEW_BUSY: dict[int | str, dict[str, Any]] = {
    429: {"model": ErrorOut, "description": "A preview of this view is already being computed for you: send the next "
                                            "one when its answer comes."}}


@contextlib.contextmanager
def _one_preview(user: str, frame_id: int) -> Iterator[None]:
    """Hold the (``user``, ``frame_id``) preview slot for the span of one preview; 429 when it is taken (a page
    keeps one preview in flight per view, so a second is a client that does not: it waits, as the page does)."""
    key = (user, frame_id)
    with _PREVIEWS_LOCK:
        if key in _PREVIEWS:
            raise HTTPException(429, detail=f"a calibration preview of frame {frame_id} is already being computed "
                                            "for you: send the next when its answer comes",
                                headers={"Retry-After": "1"})
        _PREVIEWS.add(key)
    try:
        yield
    finally:
        with _PREVIEWS_LOCK:
            _PREVIEWS.discard(key)


@router.post("/{frame_id}/calibration-preview", response_model=CalibrationPreviewOut,
             responses={**NOT_FOUND, **INVALID, **PREVIEW_BUSY, **SHARE_SPENT})
def calibration_preview(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, share: ShareDep,
                        frame_id: FrameIdPath, body: FieldLinesIn, response: Response) -> CalibrationPreviewOut:
    """The calibration these field lines would give the frame, computed as ``PUT .../field-lines`` computes it
    (the game rig's retry and a learned prior's refit included) and stored nowhere: camera, JaC, admission,
    per-class residuals and the projected pitch, for a drag that shows the camera while a point moves. Nothing is
    written or audited; ``differs`` says when the commit computes more (an ISSIA camera refined with the ball).

    422 naming ``lines``, as the edit; 429 while a preview of the same view is in flight for the same user, or while
    the user's share of computations is in use (``app.api.share``), before anything is read. The preview holds no
    database connection while it computes.
    """
    with _one_preview(principal.name, frame_id), share.turn(principal.name, "calibration preview"):
        preview = preview_calibration(session, frame_id, body.lines, settings=settings)
    response.headers["Cache-Control"] = "no-store"
    return CalibrationPreviewOut.of(preview)


@router.post("/{frame_id}/field-lines/mirror", response_model=SystemView,
             responses={**EDIT_RESPONSES, **MIRROR_REFUSED})
def mirror_field_lines(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, if_match: IfMatchDep,
                       frame_id: FrameIdPath, query: Annotated[QueueQuery, Query()], response: Response,
                       edit: EditDep) -> Response:
    """Replace the frame's field lines by their mirrored labelling (left <-> right, top <-> bottom),
    recalibrate it, and answer the recomputed system view: the fix offered for a view flagged
    ``probably_mirrored``. 422 naming ``lines`` when the frame has no field lines; 409 when the mirror
    guard refuses the mirrored calibration (nothing is stored then).
    """
    return _edited(session, response, query, principal.name, edit, lambda: editing.apply_mirrored_labels(
        session, frame_id, settings=settings, actor=principal.name,
        expected=expected_versions(if_match, "frame", frame_id), edit=edit))


@router.post("/{frame_id}/exclusion", response_model=SystemView, responses=EDIT_RESPONSES)
def set_exclusion(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, if_match: IfMatchDep,
                  frame_id: FrameIdPath, body: ExclusionIn, query: Annotated[QueueQuery, Query()],
                  response: Response, edit: EditDep) -> Response:
    """Exclude the view from its system's triangulation (``{"excluded": true}``) or restore it
    (``false``), recompute the system, and answer the recomputed system view. The decision is stored
    on the view's review and shown there (``review.excluded``); labels and calibration are kept."""
    return _edited(session, response, query, principal.name, edit, lambda: editing.set_view_excluded(
        session, frame_id, body.excluded, settings=settings, actor=principal.name,
        expected=expected_versions(if_match, "frame", frame_id), edit=edit))


@router.post("/{frame_id}/review", response_model=ReviewOut, responses=EDIT_RESPONSES)
def review_frame(session: SessionDep, principal: AnnotatorDep, if_match: IfMatchDep, frame: FrameDep, body: ReviewIn,
                 response: Response, edit: EditDep) -> ReviewOut:
    """Record the reviewer's decision on one view (for example a wrong calibration); the frame's new
    ETag in the header."""
    decision = decisions.decide_review(session, frame_id=frame.id, status=body.status, comment=body.comment,
                                       actor=principal.name, expected=expected_versions(if_match, "frame", frame.id),
                                       edit=edit)
    name_entry(edit, response)
    with_etag(response, frame_etag(writing.get_frame(session, frame.id)))
    return ReviewOut.of(decision)


@router.post("/{frame_id}/calibration-review", response_model=ReviewOut, responses=EDIT_RESPONSES)
def review_calibration(session: SessionDep, principal: AnnotatorDep, if_match: IfMatchDep, frame: FrameDep,
                       body: ReviewIn, response: Response, edit: EditDep) -> ReviewOut:
    """Record the reviewer's decision on the view's calibration (its field lines and the camera fitted to
    them), beside the decision on its ball (``POST /review``); answered as the view's decision, its
    ``calibration`` holding this one; the frame's new ETag in the header. An edit of the view's field lines
    sets a decided calibration (and its system's decision) back to pending with the reason."""
    decision = decisions.decide_calibration(session, frame.id, status=body.status, comment=body.comment,
                                            actor=principal.name,
                                            expected=expected_versions(if_match, "frame", frame.id), edit=edit)
    name_entry(edit, response)
    with_etag(response, frame_etag(writing.get_frame(session, frame.id)))
    return ReviewOut.of(decision)
