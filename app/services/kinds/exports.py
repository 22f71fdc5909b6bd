"""The export formats as plain data, the one list every other reads: each format's name, what it writes, the UI's
choices for it and which system kinds it writes; and the one selection of systems by kind that is no export
format, the monocular benchmark's reference (:data:`SELECTIONS`).

It sits with the kinds' policies, the lowest service layer, so that a policy's exports (``KindPolicy.exports``)
are read from it; the functions that write each format are bound to these entries by the export registry above
the writers (``app.services.exports.formats``: one binding per entry, checked there). A new format is one entry
here and its writers' binding there.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from app.db.models import SystemKind


@dataclass(frozen=True)
class ExportChoice:
    """One way of asking for a format: one button of the UI's exports panel.

    Attributes:
        id: the button's test id (``export-<id>``) and its row's ``data-export``; unique over every format.
        label: the button's words.
        holds: what the zip holds, in one line (the button's tooltip).
        options: the job's options this choice sets (``{"images": False}``), beside ``all``.
        download_name: the file name a download of this choice gets.
    """

    id: str
    label: str
    holds: str
    download_name: str
    options: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ExportSpec:
    """What one export format is, without how it is written.

    Attributes:
        name: ``v3d export <name>``, ``/api/exports/<name>``, the job's ``params["format"]``.
        describes: what the export writes, in a sentence or two (the command's help, the docs' table).
        choices: the UI's buttons for it, the first one the default (its options are the job's defaults).
        kinds: the system kinds whose systems it writes.
    """

    name: str
    describes: str
    choices: tuple[ExportChoice, ...]
    kinds: frozenset[SystemKind]


_SN, _SINGLE, _ISSIA = SystemKind.SOCCERNET_V3, SystemKind.SINGLE_VIEW, SystemKind.ISSIA

#: Every export format, in the UI's order. SoccerNet-v3D holds multi-view SoccerNet-v3 systems only (a single-view
#: frame leaves as cameras; exports of older versions that carried them still import); ISSIA sequences leave as
#: ISSIA-3D; the cameras export is SoccerNet-calibration JSON, which ISSIA's static cameras are not written as.
EXPORT_SPECS: tuple[ExportSpec, ...] = (
    ExportSpec(
        "soccernet-v3d",
        "Reviewed labels as a SoccerNet-v3D tree: Labels-v3D.json and Frames-v3.zip (the images, unless left out) "
        "per game, and SNv3D.csv.",
        (ExportChoice("soccernet-v3d", "SoccerNet-v3D",
                      "Labels-v3D.json and Frames-v3.zip (the images) per game, and SNv3D.csv", "soccernet-v3d.zip",
                      {"images": True}),
         ExportChoice("soccernet-v3d-no-images", "SoccerNet-v3D without images",
                      "Labels-v3D.json per game and SNv3D.csv, no images", "soccernet-v3d-no-images.zip",
                      {"images": False})),
        frozenset({_SN})),
    ExportSpec(
        "issia-3d",
        "ISSIA sequences as <sequence>/ISSIA-3D.csv (+ split.json: cameras 3-6 train, 1-2 test; "
        "calibration/cam<k>.json).",
        (ExportChoice("issia-3d", "ISSIA-3D", "per ISSIA sequence: ISSIA-3D.csv, split.json and the cameras",
                      "issia-3d.zip"),),
        frozenset({_ISSIA})),
    ExportSpec(
        "cameras",
        "The admitted cameras of SoccerNet-v3 and single-view (SoccerNet-calibration) frames as SoccerNet's "
        "calibration evaluator reads them: per image size <W>x<H>/ground_truth.zip (<split>/<name>.json field lines) "
        "and <W>x<H>/predictions.zip (camera_<name>.json), and cameras.json (names back to games and frames).",
        (ExportChoice("cameras", "Cameras", "per image size: ground_truth.zip and predictions.zip as SoccerNet's "
                      "calibration evaluator reads them", "cameras.zip"),),
        frozenset({_SN, _SINGLE})),
    ExportSpec(
        "yolo",
        "Images and labels in the Ultralytics YOLO layout (the ball is class 0: refined, else optimised box; val "
        "drawn from train, seeded), and manifest.csv/json joining each image back to its game, frame and 3D ball.",
        (ExportChoice("yolo", "YOLO", "Ultralytics layout: images/, labels/, data.yaml (relocatable: no path key)",
                      "v3d-yolo.zip"),),
        frozenset({_SN, _SINGLE, _ISSIA})),
    ExportSpec(
        "coco",
        "Images and a COCO instances JSON per split (the ball is category 1: refined, else optimised box), and "
        "manifest.csv/json joining each image back to its game, frame and 3D ball.",
        (ExportChoice("coco", "COCO", "per split: the images and instances.json", "v3d-coco.zip"),),
        frozenset({_SN, _SINGLE, _ISSIA})),
)

#: Name -> the kinds it selects, of every selection of systems by kind: each export format's and the monocular
#: benchmark's reference (``app.services.evaluation.monocular``: the balls of the views a detector is judged on,
#: every kind's).
SELECTIONS: dict[str, frozenset[SystemKind]] = {
    **{spec.name: spec.kinds for spec in EXPORT_SPECS},
    "monocular": frozenset({_SN, _SINGLE, _ISSIA}),
}

#: The names of :data:`SELECTIONS`: the exports and benchmarks that select systems by kind.
EXPORTS = frozenset(SELECTIONS)


def export_spec(name: str) -> ExportSpec:
    """The entry of the export format ``name``.

    Raises:
        ValueError: no such format.
    """
    for spec in EXPORT_SPECS:
        if spec.name == name:
            return spec
    raise ValueError(f"unknown export {name!r}; one of {', '.join(s.name for s in EXPORT_SPECS)}")


def exports_of(kind: SystemKind) -> frozenset[str]:
    """The names of :data:`SELECTIONS` that select systems of ``kind``."""
    return frozenset(name for name, kinds in SELECTIONS.items() if kind in kinds)
