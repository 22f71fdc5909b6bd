"""Pydantic schemas of ``/api/predictions`` (``app.api.routes.predictions``): the ball detectors' predictions stored,
one summary per source (``app.services.transfer.prediction_sources``), and what removing one did."""
from __future__ import annotations

from datetime import datetime
from typing import Optional

from pydantic import BaseModel, Field


class ScoreSpreadOut(BaseModel):
    """The spread of a source's scores (the detector's confidence, 0-1 for most detectors)."""

    min: Optional[float]
    q1: Optional[float] = Field(description="First quartile.")
    median: Optional[float]
    q3: Optional[float] = Field(description="Third quartile.")
    max: Optional[float]


class PredictionSourceOut(BaseModel):
    """One detector's stored predictions."""

    source: str = Field(description="The detector's name, as imported.")
    predictions: int = Field(description="Ball boxes stored.")
    frames: int = Field(description="Views they lie on.")
    systems: int = Field(description="Systems those views belong to.")
    scores: ScoreSpreadOut
    imported_at: Optional[datetime] = Field(description="When it was last imported (UTC); null: unknown.")
    imported_by: Optional[str] = Field(description="Who imported it: a user's name or 'command line' (with the OS "
                                                   "account for admins); null: unknown (no import entry names it).")


class PredictionSourcesOut(BaseModel):
    items: list[PredictionSourceOut]


class PredictionsRemovedOut(BaseModel):
    """What removing a source did."""

    source: str
    removed: int = Field(description="Predictions deleted (labels placed from them stay).")
