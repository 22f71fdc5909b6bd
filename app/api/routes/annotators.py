"""``GET /api/stats/annotators``: the per-annotator figures (``app.services.evaluation.annotators``), for reviewers and
admins; all time by default, ``since`` / ``until`` (ISO 8601, UTC when no offset is given) bound the entries' times,
``format=csv`` answers ``text/csv`` whose header row is the JSON's keys."""
from __future__ import annotations

import csv
import io
from typing import Annotated, Literal, Optional

from fastapi import APIRouter, Query, Response

from app.api.annotator_schemas import AnnotatorOut, AnnotatorsOut
from app.api.auth import ReviewerDep
from app.api.deps import SessionDep
from app.api.schemas import INVALID, UtcTime
from app.core.errors import InvalidInputError
from app.datasets.csv_cells import inert_cell
from app.services.evaluation.annotators import FIELDS, annotator_figures

router = APIRouter(tags=["stats"])


@router.get("/stats/annotators", response_model=AnnotatorsOut, responses={**INVALID, 200: {
    "content": {"text/csv": {}}, "description": "The figures (JSON, or CSV with format=csv)."}})
def annotators(session: SessionDep, principal: ReviewerDep,
               since: Annotated[Optional[UtcTime], Query(description="Only entries at or after this time (UTC).")]
               = None,
               until: Annotated[Optional[UtcTime], Query(description="Only entries before this time (UTC).")] = None,
               format: Annotated[Literal["json", "csv"], Query(description="csv: text/csv, header row = the keys.")]
               = "json") -> AnnotatorsOut | Response:
    """Per-person figures: as an annotator, edits, systems touched and decided, needs fix received, accepted at first
    review, the median time from edit to review, and the geometry's word on their ball labels (median distance from
    the ball the other views agree on, share accused by a doubt); as a reviewer, the system decisions made (accepted,
    rejected, needs fix) and the re-reviews of systems that came back fixed. Reviewers and admins. 422 naming
    ``until`` when it is not after ``since``."""
    if since is not None and until is not None and until <= since:
        raise InvalidInputError("until must be after since", field="until")
    items = [AnnotatorOut(**f.as_dict()) for f in annotator_figures(session, since, until)]
    if format == "csv":
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(FIELDS)
        for item in items:
            row = item.model_dump()
            writer.writerow([inert_cell(str(row[k])) if isinstance(row[k], str) else
                             "" if row[k] is None else row[k] for k in FIELDS])
        return Response(out.getvalue(), media_type="text/csv; charset=utf-8",
                        headers={"Content-Disposition": 'attachment; filename="annotators.csv"'})
    return AnnotatorsOut(items=items)
