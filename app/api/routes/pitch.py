"""``/api/pitch-model``: the pitch model's field-line classes, so that pages choose a line's class from the
list the calibration knows (``app.geometry.pitch``) instead of a copy of it."""
from __future__ import annotations

from fastapi import APIRouter, Response

from app.api.pitch_schemas import PitchModelOut

router = APIRouter(prefix="/pitch-model", tags=["pitch"])

#: The model is part of the code: it changes only with a new version of the server.
PITCH_CACHE_CONTROL = "private, max-age=3600"


@router.get("", response_model=PitchModelOut)
def pitch_model(response: Response) -> PitchModelOut:
    """The field-line classes (SoccerNet names, in SoccerNet's order; each with its mirrored class and whether
    the pitch model has an element for it) and the pitch's length and width in metres."""
    response.headers["Cache-Control"] = PITCH_CACHE_CONTROL
    return PitchModelOut.of_model()
