"""Pydantic schemas of the background-job routes: imports (a path or an upload), export jobs, and the
jobs themselves (``app.services.jobs.runner``). Apart from ``app.api.schemas``: the jobs' contract is its own idea."""
from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.api.schemas import _In
from app.db.models import JobState
from app.services.jobs.work import WORK
from app.services.kinds import POLICIES
from app.services.transfer.import_formats import refused_options
from app.services.transfer.merging import MERGE_MODES

#: The dataset formats an import takes: every kind's ``import_formats``, once each, in the kinds' order.
#: What a job runs (``app.services.jobs.work.WORK``) and where it is (``JobState``).
#: How an import merges games stored already (``app.services.transfer.merging.MERGE_MODES``).
if TYPE_CHECKING:  # mypy cannot build a Literal from values computed at import
    ImportFormat = str
    JobKindName = str
    JobStateName = str
    MergeMode = str
else:
    # the kinds' dataset formats, then a detector's predictions (rows on stored frames, no systems of a kind)
    ImportFormat = Literal[(*dict.fromkeys(f for p in POLICIES.values() for f in p.import_formats), "predictions")]
    JobKindName = Literal[tuple(WORK)]
    JobStateName = Literal[tuple(s.value for s in JobState)]
    MergeMode = Literal[tuple(MERGE_MODES)]

_MERGE = ("Games stored already: how to merge them (without it an import of a stored game is refused with 409 "
          "naming the games). " + "; ".join(f"{mode}: {what}" for mode, what in MERGE_MODES.items()) + ".")


class ImportOptions(_In):
    """How to read a dataset to import (the form fields of an upload; :class:`ImportIn` adds the path)."""

    kind: ImportFormat = Field(
        description="Dataset layout: SoccerNet-v3 tree, SoccerNet-v3D export, SoccerNet-calibration set, ISSIA folder; "
                    "or a ball detector's predictions (CSV league,season,match,image,x1,y1,x2,y2,score).")
    width: Optional[int] = Field(None, gt=1, le=65535, description="sn-calibration only: image width (px) when there "
                                                                  "are no images.")
    height: Optional[int] = Field(None, gt=1, le=65535, description="sn-calibration only: image height (px) when "
                                                                   "there are no images.")
    from_lines: bool = Field(False, description="issia only: calibrate each static camera from issia_lines.json "
                                                "even when issia_calibration.json is present.")
    flip: list[str] = Field(default_factory=list, description="issia only: camera ids ('1'..'6') whose footage is "
                                                              "mirrored horizontally (images only).")
    merge: Optional[MergeMode] = Field(None, description=_MERGE)
    source: Optional[str] = Field(None, pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$",
                                  description="predictions only: the detector's name (e.g. yolo-sn-ball; default: the "
                                              "file's stem). Importing a source again replaces its predictions.")

    @model_validator(mode="after")
    def _size_for_calibration_only(self) -> "ImportOptions":
        why = refused_options(self.kind, self.model_dump(include={"width", "height", "from_lines", "flip", "source"}))
        if why:
            raise ValueError(why)
        return self


class ImportIn(ImportOptions):
    """A dataset on the server's disk to import (for scripts)."""

    path: str = Field(min_length=1, description="Folder or archive on the server, under V3D_DATA_ROOT.")


class ImportUploadIn(BaseModel):
    """The multipart form of an uploaded dataset (documentation of ``POST /api/imports``)."""

    file: bytes = Field(json_schema_extra={"format": "binary"}, description="A zip of the dataset (e.g. "
                        "<league>/<season>/<game>/Labels-v3.json and Frames-v3.zip for kind soccernet-v3).")
    kind: ImportFormat
    width: Optional[int] = Field(None, gt=1, le=65535)
    height: Optional[int] = Field(None, gt=1, le=65535)
    from_lines: bool = False
    flip: Optional[str] = Field(None, description="Comma-separated camera ids (issia only).")
    merge: Optional[MergeMode] = Field(None, description=_MERGE)
    source: Optional[str] = Field(None, description="predictions only: the detector's name.")


_RELEASE = ("The release to export (its accepted systems as they were when it was made) instead of the database "
            "now: the same release exports byte for byte the same. Not with 'all' (422).")


class _ExportIn(_In):
    all: bool = Field(False, strict=True, description="Every system, not only the accepted ones.")
    release: Optional[str] = Field(None, min_length=1, max_length=200, description=_RELEASE)

    @model_validator(mode="after")
    def _release_alone(self) -> "_ExportIn":
        if self.all and self.release is not None:
            raise ValueError("a release holds its accepted systems only: 'all' and 'release' exclude each other")
        return self


class ExportJobIn(_ExportIn):
    """An export to run as a background job."""

    images: bool = Field(True, strict=True, description="Each game's Frames-v3.zip (its images) beside its "
                                                       "Labels-v3D.json; false leaves them out.")


class TreeExportJobIn(_ExportIn):
    """An export other than SoccerNet-v3D to run as a background job."""


class BackupIn(_In):
    """A backup of the whole deployment to run as a background job (``v3d backup``)."""

    local_files: bool = Field(True, strict=True, description="The images of datasets read from the server's own "
                                                             "folders (command-line imports, the demo) too; false "
                                                             "lists their folders in the manifest instead.")


class JobOut(BaseModel):
    """A background job (``app.services.jobs.runner``): its progress while it runs, its result when done."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    kind: JobKindName
    params: dict[str, Any] = Field(description="What it runs (an import's kind and path, an export's 'all').")
    state: JobStateName
    stage: Optional[str] = Field(description="The step it is in: games, merge, calibrate, rig, triangulate, "
                                             "predictions, recompute, export.")
    done: int = Field(description="Items of the stage done.")
    total: int = Field(description="Items of the stage in all (0: unknown).")
    message: Optional[str] = Field(description="Why it failed (a dataset error names the file and field).")
    result: Optional[dict[str, Any]] = Field(description="An import's counts, a recompute's, an export's file size "
                                                         "and counts.")
    owner: Optional[str] = Field(description="node:pid:token of the process running it, node being V3D_NODE_NAME "
                                             "(admins only; null for the other roles).")
    attempts: int = Field(description="How many times a runner claimed it (more than 1: resumed).")
    created_at: datetime
    started_at: Optional[datetime]
    finished_at: Optional[datetime]
    heartbeat_at: Optional[datetime]
    url: str = Field(description="This job's URL.")
    result_url: Optional[str] = Field(description="Where a finished export's file is downloaded.")


class JobPageOut(BaseModel):
    """A page of jobs, newest first."""

    items: list[JobOut]
    total: int
    limit: int
    offset: int
