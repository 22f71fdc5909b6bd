"""``v3d jac``: SoccerNet's official camera-calibration score for a set of camera predictions.

Registered on :data:`app.cli._root.cli`. The scoring is :func:`app.geometry.jac.evaluate_jac`; this
module only reads the inputs, aggregates as SoccerNet's ``CameraCalibration.evaluate`` does
(PyPI ``SoccerNet``, ``SoccerNet/Evaluation/CameraCalibration.py``) and prints:

* completeness = frames with a camera / annotated frames;
* mean JaC = mean over the frames **with** a camera;
* final score = completeness x mean JaC.
"""
from __future__ import annotations

import json
import math
from pathlib import Path, PurePosixPath
from typing import Annotated, Any, Optional

import typer

from app.cli._root import cli
from app.cli.errors import fail
from app.datasets.files import InputFileError, JsonFile, json_files
from app.geometry.annotations import AnnotationError, from_soccernet_calibration
from app.geometry.camera import Camera
from app.geometry.jac import OFFICIAL_THRESHOLDS_PX, evaluate_jac, gamma_thresholds

_CAMERA_PREFIX = "camera_"


#: An input of ``v3d jac`` cannot be used; the message names the path or file at fault.
JaCInputError = InputFileError


def _by_frame(files: list[JsonFile], what: str, prefix: str = "") -> dict[str, JsonFile]:
    """Frame id -> file, the id being the file name's stem without ``prefix``."""
    out: dict[str, JsonFile] = {}
    for f in files:
        stem = PurePosixPath(f.name).stem
        if not stem.startswith(prefix):
            continue
        frame = stem[len(prefix):]
        if frame in out:
            raise JaCInputError(f"{what}: frame {frame!r} appears twice: {out[frame].label} and {f.label}")
        out[frame] = f
    return out


def _frame_order(frame: str) -> tuple[int, int | str]:
    return (0, int(frame)) if frame.isdigit() else (1, frame)


def _parse_floats(text: str, option: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError as exc:
        raise JaCInputError(f"{option}: expected comma-separated numbers, got {text!r}") from exc
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise JaCInputError(f"{option}: expected positive numbers, got {text!r}")
    return values


def score_folder(annotations: Path, cameras: Path, width: int, height: int,
                 thresholds_px: tuple[float, ...]) -> dict[str, Optional[list[float]]]:
    """JaC of every annotated frame: frame id -> one value per threshold, or None without a camera.

    Args:
        annotations: folder or zip of SoccerNet-calibration frame JSON files (``<frame>.json``,
            normalised points).
        cameras: folder or zip of ``camera_<frame>.json`` (SoccerNet camera JSON, expressed at
            ``width`` x ``height``).
        width, height: evaluation resolution, pixels.
        thresholds_px: thresholds, pixels.

    Raises:
        JaCInputError: a missing path, no annotation file, unreadable JSON, a malformed annotation or
            camera (the message names the file).
    """
    frames = _by_frame(json_files(annotations, "ANNOTATIONS"), "ANNOTATIONS")
    if not frames:
        raise JaCInputError(f"ANNOTATIONS: no *.json annotation file in {annotations}")
    cams = _by_frame(json_files(cameras, "CAMERAS"), "CAMERAS", _CAMERA_PREFIX)
    out: dict[str, Optional[list[float]]] = {}
    for frame in sorted(frames, key=_frame_order):
        if frame not in cams:
            out[frame] = None
            continue
        try:
            lines = from_soccernet_calibration(frames[frame].load(), width, height)
        except AnnotationError as exc:
            raise JaCInputError(f"{frames[frame].label}: {exc}") from exc
        try:
            camera = Camera.from_soccernet(cams[frame].load())
        except (ValueError, TypeError) as exc:
            raise JaCInputError(f"{cams[frame].label}: {exc}") from exc
        result = evaluate_jac(camera, lines, width, height, thresholds_px)
        out[frame] = [t.jac for t in result.per_threshold]
    return out


def summarise(per_frame: dict[str, Optional[list[float]]], n_thresholds: int) -> dict[str, Any]:
    """Completeness, mean JaC over frames with a camera and final score (completeness x mean), per
    threshold, as SoccerNet's ``CameraCalibration.evaluate``. Means are 0 when no frame has a camera."""
    scored = [v for v in per_frame.values() if v is not None]
    completeness = len(scored) / len(per_frame) if per_frame else 0.0
    means = [sum(v[i] for v in scored) / len(scored) if scored else 0.0 for i in range(n_thresholds)]
    return {"frames": len(per_frame), "with_camera": len(scored), "completeness": completeness,
            "mean_jac": means, "final_score": [completeness * m for m in means]}


@cli.command("jac")
def jac_command(
    annotations: Annotated[Path, typer.Argument(
        help="Folder or zip of SoccerNet-calibration frame JSON (<frame>.json).")],
    cameras: Annotated[Path, typer.Argument(help="Folder or zip of camera_<frame>.json predictions.")],
    width: Annotated[int, typer.Option(
        "--width", min=2, help="Evaluation width, pixels (cameras must be at this size).")] = 960,
    height: Annotated[int, typer.Option("--height", min=2, help="Evaluation height, pixels.")] = 540,
    thresholds: Annotated[Optional[str], typer.Option(
        "--thresholds", help="Thresholds in pixels, e.g. 5,10,20 (default).")] = None,
    gammas: Annotated[Optional[str], typer.Option(
        "--gammas", help="Thresholds as fractions of the image diagonal, e.g. 0.005,0.01,0.02.")] = None,
    json_out: Annotated[Optional[Path], typer.Option(
        "--json", help="Write per-frame JaC and the summary to this file.")] = None,
) -> None:
    """Official SoccerNet JaC (completeness, mean JaC, final score) of camera predictions."""
    try:
        if thresholds is not None and gammas is not None:
            raise JaCInputError("give either --thresholds or --gammas, not both")
        gamma_values = _parse_floats(gammas, "--gammas") if gammas is not None else None
        if gamma_values is not None:
            thresholds_px = gamma_thresholds(width, height, gamma_values)
        elif thresholds is not None:
            thresholds_px = _parse_floats(thresholds, "--thresholds")
        else:
            thresholds_px = OFFICIAL_THRESHOLDS_PX
        per_frame = score_folder(annotations, cameras, width, height, thresholds_px)
    except JaCInputError as exc:
        raise fail(str(exc)) from exc
    summary = summarise(per_frame, len(thresholds_px))
    typer.echo(f"{summary['frames']} annotated frames, {summary['with_camera']} with a camera: "
               f"completeness {summary['completeness']:.4f} ({width}x{height})")
    typer.echo(f"{'threshold':>20}  {'mean JaC':>8}  {'final score':>11}")
    labels = ([f"{g:g} diag ({t:.2f} px)" for g, t in zip(gamma_values, thresholds_px, strict=True)] if gamma_values
              else [f"{t:g} px" for t in thresholds_px])
    for label, mean, final in zip(labels, summary["mean_jac"], summary["final_score"], strict=True):
        typer.echo(f"{label:>20}  {mean:8.4f}  {final:11.4f}")
    if json_out is not None:
        payload = {"width": width, "height": height, "thresholds_px": list(thresholds_px),
                   "gammas": list(gamma_values) if gamma_values else None,
                   "frame_count": summary["frames"], "with_camera": summary["with_camera"],
                   "completeness": summary["completeness"], "mean_jac": summary["mean_jac"],
                   "final_score": summary["final_score"], "frames": per_frame}
        try:
            json_out.write_text(json.dumps(payload, indent=1))
        except OSError as exc:
            raise fail(f"--json: cannot write {json_out}: {exc}") from exc
        typer.echo(f"per-frame values written to {json_out}")
