"""The API's schema of the pitch model (``GET /api/pitch``): the field-line classes a label may carry and the
pitch's size, as ``app.geometry.pitch`` defines them."""
from __future__ import annotations

from pydantic import BaseModel, Field

from app.geometry import pitch


class PitchClassOut(BaseModel):
    """One field-line class of the pitch model (SoccerNet's name, trailing space included)."""

    name: str
    mirror: str = Field(description="The class it becomes when the pitch is turned 180 degrees.")
    modelled: bool = Field(
        description="False for 'Goal unknown' and 'Line unknown': valid labels the geometry ignores.")


class PitchModelOut(BaseModel):
    """The pitch model the calibration fits lines to (``app.geometry.pitch``): the classes a field line may
    carry, in SoccerNet's order, and the pitch's size (metres)."""

    classes: list[PitchClassOut]
    length_m: float
    width_m: float

    @classmethod
    def of_model(cls) -> "PitchModelOut":
        return cls(classes=[PitchClassOut(name=c, mirror=pitch.MIRROR_CLASSES[c],
                                          modelled=c not in pitch.UNKNOWN_CLASSES)
                            for c in pitch.LINE_CLASSES],
                   length_m=pitch.PITCH_LENGTH_M, width_m=pitch.PITCH_WIDTH_M)
