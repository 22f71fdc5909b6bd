"""A release's documents as typed values: what a release stores of a game and of a system, by document version.

A release stores canonical JSON documents (``app.services.releases.content``: one per released game and system,
each a gzip member named by its digest). The document's shape is a promise: a release's exports are rendered from
its documents (``app.services.releases.export``), never from the database as it is now, so the documents must be
read as they were written whatever the live export selects later. This module is that shape, written once per
document version:

* :data:`DOCUMENT_VERSION` is the version a release writes now (``content.game_document``,
  ``content.system_document``);
* a document states its version in the key ``document_version``; a document without it is version 1 (every
  document stored before versions were named: writing the key into version 1 would change every digest, and so
  every release's hash);
* :func:`read_game` and :func:`read_system` read every version ever written (:data:`READERS`), so a version
  written once is read, and rendered, forever. A new version adds its classes and reader here and leaves the older
  ones as they are; the golden files of ``tests/services/releases/golden`` hold one stored document per format
  with its exact export bytes.

Version 1 (module docstring of ``app.services.releases.content`` for what each key means): the JSON values are kept
as they were stored (the stored JSON columns as their text, enums by value, numbers as they were), never mapped
to the live enums or models, which may change.

Version 2 (releases made since systems are accepted in batches after a sample): a system's document is version 1's
with ``document_version`` 2 and ``accepted`` (:class:`AcceptanceDocument`: by a person, or in a batch after a sample
with its plan). Its game documents are version 1's. A release made before keeps its version 1 documents, so its
exports are the same bytes; the formats render both versions alike (``render.v1``): how a system was accepted is in
the release's documents (``v3d-release/documents.jsonl.gz`` of every export), not in the format files.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any, Optional

#: The version of the documents a release writes now: 2, a system's document saying how it was accepted
#: (:class:`AcceptanceDocument`); its game documents are those of version 1 (no version key).
DOCUMENT_VERSION = 2
#: The key naming a document's version (absent: version 1).
VERSION_KEY = "document_version"


@dataclass(frozen=True)
class GameDocument:
    """A released game (version 1): its id, folder names (league, season, match, ``path``), what its imported
    labels file carried beside its systems (``release``, a JSON object or None) and ``as_of`` (ISO 8601 UTC: the
    time of its newest change the release holds)."""

    game_id: int
    league: str
    season: str
    match: str
    path: str
    release: Optional[dict[str, Any]]
    as_of: str

    def as_json(self) -> dict[str, Any]:
        """The document as stored (version 1: no version key)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class TriangulationDocument:
    """A released system's triangulation (version 1): its status (value of ``TriangulationStatus``), the settings
    it was computed with (``tau_px`` px, ``rule``, ``min_baseline_m`` m) and, per pair of admitted views,
    ``(frame a id, frame b id, kept)`` (empty in documents written before pairs were kept)."""

    status: Optional[str]
    tau_px: Optional[float]
    rule: Optional[str]
    min_baseline_m: Optional[float]
    pairs: tuple[tuple[int, int, bool], ...] = ()

    def as_json(self) -> dict[str, Any]:
        """The triangulation as its system's document stores it."""
        return {"status": self.status, "tau_px": self.tau_px, "rule": self.rule,
                "min_baseline_m": self.min_baseline_m, "pairs": [list(p) for p in self.pairs]}


@dataclass(frozen=True)
class TrajectoryDocument:
    """An ISSIA frame's point on its sequence's fitted trajectory (version 1): ``ball3d`` and ``ball3d_smoothed``
    (world metres ``[x, y, z]``, SoccerNet frame, z down, or None), ``source`` and ``cam_list`` (the frame ids of
    the labels it kept)."""

    ball3d: Optional[list[float]]
    ball3d_smoothed: Optional[list[float]]
    source: Optional[str]
    cam_list: list[int]

    def as_json(self) -> dict[str, Any]:
        """The point as its system's document stores it."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class FrameDocument:
    """One released view (version 1): the columns of its export row (``exporting.frame_row_select`` as it was
    when version 1 was written) but the system's, and its view decisions. JSON values are their stored text
    (``*_json``, ``ball_box``, ``ball_point``, ``original_box``, ``original_point``, ``opt_box``; None for SQL
    NULL); ``role``, ``cal_source``, ``cal_status``, ``view_status`` and ``view_calibration_status`` enums by
    value; ``width``/``height`` px; ``rep_error_px``, ``opt_d_px`` px; ``opt_error_m`` m."""

    frame_id: int
    name: str
    role: str
    width: int
    height: int
    frame_split: Optional[str]
    cal_source: Optional[str]
    cal_status: Optional[str]
    camera_json: Optional[str]
    reason: Optional[str]
    flags_json: Optional[str]
    residuals_json: Optional[str]
    uncertainty_json: Optional[str]
    admitted: Optional[bool]
    jac_0005: Optional[float]
    jac_001: Optional[float]
    jac_002: Optional[float]
    lines_json: Optional[str]
    original_json: Optional[str]
    label_frame: Optional[int]
    ball_kind: Optional[str]
    ball_box: Optional[str]
    ball_point: Optional[str]
    original_box: Optional[str]
    original_point: Optional[str]
    opt_box: Optional[str]
    opt_d_px: Optional[float]
    opt_error_m: Optional[float]
    rep_error_px: Optional[float]
    release_json: Optional[str]
    view_status: Optional[str]
    view_calibration_status: Optional[str]
    excluded: Optional[bool]

    def as_json(self) -> dict[str, Any]:
        """The view as its system's document stores it."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class AcceptanceDocument:
    """How a released system was accepted (version 2): ``how`` is ``person`` (a person's decision) or ``batch`` (in a
    batch of vouched systems after a random sample, ``app.services.curation.batches``: ``batch_id``, the plan's
    ``confidence`` and ``max_wrong_share`` (fractions), ``sample`` systems reviewed of the batch's ``systems``, and
    the ``plan`` in words); the batch's fields are None for a person's."""

    how: str
    batch_id: Optional[int] = None
    confidence: Optional[float] = None
    max_wrong_share: Optional[float] = None
    sample: Optional[int] = None
    systems: Optional[int] = None
    plan: Optional[str] = None

    def as_json(self) -> dict[str, Any]:
        """As a system's document stores it: ``{"how": "person"}``, or every field for a batch's."""
        if self.how != "batch":
            return {"how": self.how}
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class SystemDocument:
    """A released multi-view system (version 1): its id, name, kind (value of ``SystemKind``), game id, review
    status (value of ``ReviewStatus``), ``ball3d`` (the triangulated ball as its stored JSON text: world metres
    ``[x, y, z]``, z down), triangulation, ``derived_settings`` (``Settings.derived_fingerprint``),
    ``derived_version``, ``frame_index`` (ISSIA), its views in order and, for an ISSIA frame, its trajectory point.
    """

    system_id: int
    name: str
    kind: str
    game_id: int
    review_status: Optional[str]
    ball3d: Optional[str]
    triangulation: Optional[TriangulationDocument]
    derived_settings: Optional[str]
    derived_version: Optional[int]
    frame_index: Optional[int]
    frames: tuple[FrameDocument, ...]
    trajectory: Optional[TrajectoryDocument] = None
    #: How it was accepted (version 2; None in a version 1 document, written before releases said it).
    accepted: Optional[AcceptanceDocument] = None

    @property
    def has_ball3d(self) -> bool:
        """Whether the system was released with a 3D ball (``ball3d`` neither SQL NULL nor JSON null: an accepted
        system whose views agreed on no ball has none)."""
        return self.ball3d not in (None, "null")

    def as_json(self) -> dict[str, Any]:
        """The document as stored: version 1 (no version key; ``trajectory`` only where there is one) without
        ``accepted``, else version 2 (its ``document_version`` and ``accepted`` beside version 1's keys)."""
        out = {"system_id": self.system_id, "name": self.name, "kind": self.kind, "game_id": self.game_id,
               "review_status": self.review_status, "ball3d": self.ball3d,
               "triangulation": None if self.triangulation is None else self.triangulation.as_json(),
               "derived_settings": self.derived_settings, "derived_version": self.derived_version,
               "frame_index": self.frame_index, "frames": [f.as_json() for f in self.frames]}
        if self.trajectory is not None:
            out["trajectory"] = self.trajectory.as_json()
        if self.accepted is not None:
            out[VERSION_KEY], out["accepted"] = 2, self.accepted.as_json()
        return out


def document_version(data: Mapping[str, Any]) -> int:
    """The version of a stored document (parsed JSON): its ``document_version``, 1 without one.

    Raises:
        ValueError: a version no reader knows (a document written by a later v3d).
    """
    version = data.get(VERSION_KEY, 1)
    if version not in READERS:
        raise ValueError(f"release document version {version!r} is unknown here (known: {sorted(READERS)}); "
                         "a later v3d wrote it")
    return int(version)


def _game_v1(data: Mapping[str, Any]) -> GameDocument:
    return GameDocument(game_id=data["game_id"], league=data["league"], season=data["season"], match=data["match"],
                        path=data["path"], release=data["release"], as_of=data["as_of"])


#: The keys of a version 1 view, in the order of its fields.
FRAME_KEYS = tuple(f.name for f in fields(FrameDocument))


def _system_v1(data: Mapping[str, Any]) -> SystemDocument:
    tri = data["triangulation"]
    trajectory = data.get("trajectory")  # ISSIA frames only
    return SystemDocument(
        system_id=data["system_id"], name=data["name"], kind=data["kind"], game_id=data["game_id"],
        review_status=data["review_status"], ball3d=data["ball3d"],
        triangulation=None if tri is None else TriangulationDocument(
            status=tri["status"], tau_px=tri["tau_px"], rule=tri["rule"], min_baseline_m=tri["min_baseline_m"],
            pairs=tuple((int(a), int(b), bool(k)) for a, b, k in tri.get("pairs", []))),
        # documents written before these were kept lack them
        derived_settings=data.get("derived_settings"), derived_version=data.get("derived_version"),
        frame_index=data.get("frame_index"),
        frames=tuple(FrameDocument(**{k: f[k] for k in FRAME_KEYS}) for f in data["frames"]),
        trajectory=None if trajectory is None else TrajectoryDocument(
            ball3d=trajectory["ball3d"], ball3d_smoothed=trajectory["ball3d_smoothed"], source=trajectory["source"],
            cam_list=list(trajectory["cam_list"])))


def _system_v2(data: Mapping[str, Any]) -> SystemDocument:
    """Version 2: version 1 and how the system was accepted."""
    accepted = data["accepted"]
    return dataclasses.replace(_system_v1(data), accepted=AcceptanceDocument(
        how=accepted["how"], batch_id=accepted.get("batch_id"), confidence=accepted.get("confidence"),
        max_wrong_share=accepted.get("max_wrong_share"), sample=accepted.get("sample"),
        systems=accepted.get("systems"), plan=accepted.get("plan")))


#: Per document version ever written: (game reader, system reader), each from the parsed stored JSON. Never
#: remove or change one: releases written with it are read with it. Version 2 changed the system documents only.
READERS: dict[int, tuple[Callable[[Mapping[str, Any]], GameDocument],
                         Callable[[Mapping[str, Any]], SystemDocument]]] = {1: (_game_v1, _system_v1),
                                                                            2: (_game_v1, _system_v2)}


def read_game(data: Mapping[str, Any]) -> GameDocument:
    """A stored game document (parsed JSON, any version :data:`READERS` knows) as a :class:`GameDocument`.

    Raises:
        ValueError: an unknown version. KeyError: a key its version writes is missing (a damaged document).
    """
    return READERS[document_version(data)][0](data)


def read_system(data: Mapping[str, Any]) -> SystemDocument:
    """A stored system document (parsed JSON, any version :data:`READERS` knows) as a :class:`SystemDocument`.

    Raises:
        ValueError: an unknown version. KeyError: a key its version writes is missing (a damaged document).
    """
    return READERS[document_version(data)][1](data)
