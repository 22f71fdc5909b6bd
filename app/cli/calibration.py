"""``v3d calibrate``: calibrate SoccerNet-calibration frames offline from their field lines.

Registered on :data:`app.cli._root.cli`. No database: reads a folder or a zip of frame JSON files
(``<frame>.json``, normalised points), calibrates every frame with
:func:`app.geometry.calibration.calibrate_frame` in the service's process pool
(``app.services.calibration.pool.calibration_pool``), writes one
``camera_<frame>.json`` (SoccerNet camera format, ``Camera.to_soccernet()``) per calibrated frame and
``calibration_summary.json`` (status, reason, flags, residuals per frame), and prints a summary. The
output folder is what ``v3d jac ANNOTATIONS OUT_DIR`` scores.
"""
from __future__ import annotations

import collections
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Iterator, Optional

import typer
from tqdm import tqdm

from app.cli._root import cli
from app.core.errors import DatasetError
from app.datasets.sn_calibration import CALIBRATION_SUMMARY, frame_entries
from app.geometry.annotations import AnnotationError, from_soccernet_calibration
from app.geometry.calibration import CalibrationPrior, calibrate_frame
from app.services.calibration.pool import calibration_pool
from app.services.wording.words import refusal_sentence

SUMMARY_FILE = CALIBRATION_SUMMARY


@dataclass(frozen=True)
class FrameOutcome:
    """What happened to one frame (picklable, sent back by the workers)."""

    frame: str
    status: str  # "calibrated" | "refused" | "unreadable"
    reason: Optional[str]
    camera: Optional[dict[str, Any]]
    flags: tuple[str, ...]
    residuals_px: dict[str, float]
    rms_px: Optional[float]
    elapsed_ms: float


def read_frames(path: Path) -> Iterator[tuple[str, bytes]]:
    """``(frame id, JSON bytes)`` of every frame of a SoccerNet-calibration folder or zip, as the import
    reads them (:func:`app.datasets.sn_calibration.frame_entries`: sub-folders included, named by stem,
    ``camera_*.json`` and :data:`SUMMARY_FILE` skipped).

    Raises:
        typer.BadParameter: ``path`` is missing or neither a folder nor a zip archive, or holds two
            frames of one name.
    """
    try:
        for name, _where, raw, _image in frame_entries(path):
            yield name, raw
    except DatasetError as exc:
        raise typer.BadParameter(str(exc), param_hint="ANNOTATIONS") from None


def calibrate_one(job: tuple[str, bytes, int, int, Optional[int]]) -> FrameOutcome:
    """Worker: parse one frame and calibrate it; never raises (bad files come back ``unreadable``)."""
    frame, data, width, height, side = job
    t0 = time.perf_counter()
    try:
        lines = from_soccernet_calibration(json.loads(data.decode("utf-8")), width, height)
    except (UnicodeDecodeError, json.JSONDecodeError, AnnotationError) as exc:
        return FrameOutcome(frame, "unreadable", f"{frame}.json: {exc}", None, (), {}, None,
                            (time.perf_counter() - t0) * 1e3)
    prior = CalibrationPrior(expected_side=side) if side is not None else None
    r = calibrate_frame(lines, width, height, prior=prior, compute_jac=False)
    return FrameOutcome(frame, r.status, refusal_sentence(r.refusal),
                        r.camera.to_soccernet() if r.camera is not None else None,
                        r.flags, dict(r.residuals_px), r.rms_px, r.elapsed_ms)


def _side(value: str) -> Optional[int]:
    v = value.strip().lower()
    if v in ("none", ""):
        return None
    if v in ("+1", "1", "positive", "y>0"):
        return 1
    if v in ("-1", "negative", "y<0"):
        return -1
    raise typer.BadParameter("must be +1 (cameras on the y > 0 side), -1 or none", param_hint="--expected-side")


@cli.command("calibrate")
def calibrate_command(
    annotations: Annotated[Path, typer.Argument(help="Folder or zip of SoccerNet-calibration frame JSON files.")],
    out_dir: Annotated[Path, typer.Argument(help="Folder for camera_<frame>.json files (created if needed).")],
    width: Annotated[int, typer.Option("--width", min=2,
                                       help="Image width in pixels (normalised points are scaled by W - 1).")] = 960,
    height: Annotated[int, typer.Option("--height", min=2, help="Image height in pixels.")] = 540,
    workers: Annotated[int, typer.Option("--workers", min=0, help="Worker processes; 0 = one per core.")] = 0,
    expected_side: Annotated[str, typer.Option(
        "--expected-side",
        help="Side of the pitch the cameras are expected on, only to flag probably mirrored labels: "
             "+1 (y > 0, broadcast main cameras), -1, or none.")] = "none",
) -> None:
    """Calibrate every frame from its field lines; write SoccerNet camera files and a summary."""
    side = _side(expected_side)
    frames = list(read_frames(annotations))
    if not frames:
        raise typer.BadParameter(f"no *.json frame found in {annotations}", param_hint="ANNOTATIONS")
    out_dir.mkdir(parents=True, exist_ok=True)
    jobs = [(frame, data, width, height, side) for frame, data in frames]
    outcomes: list[FrameOutcome] = []
    t0 = time.perf_counter()
    with calibration_pool(workers) as pool, tqdm(total=len(jobs), desc="calibrate", unit="frame") as bar:
        n_workers = pool.workers
        for outcome in pool.map(calibrate_one, jobs, chunksize=8):
            outcomes.append(outcome)
            bar.update()
    seconds = time.perf_counter() - t0
    outcomes.sort(key=lambda o: o.frame)
    for o in outcomes:
        if o.camera is not None:
            (out_dir / f"camera_{o.frame}.json").write_text(json.dumps(o.camera, indent=1))
    summary = {o.frame: {"status": o.status, "reason": o.reason, "flags": list(o.flags),
                         "residuals_px": o.residuals_px, "rms_px": o.rms_px, "elapsed_ms": round(o.elapsed_ms, 2)}
               for o in outcomes}
    (out_dir / SUMMARY_FILE).write_text(json.dumps(summary, indent=1))
    counts = collections.Counter(o.status for o in outcomes)
    typer.echo(f"{len(outcomes)} frames in {seconds:.1f} s ({n_workers} workers): "
               f"{counts['calibrated']} calibrated, {counts['refused']} refused, {counts['unreadable']} unreadable")
    flagged = collections.Counter(f.split(":")[0] for o in outcomes for f in o.flags)
    if flagged:
        typer.echo("flags: " + ", ".join(f"{k} {v}" for k, v in sorted(flagged.items())))
    for o in outcomes:
        if o.status != "calibrated":
            typer.echo(f"  {o.status} {o.frame}: {o.reason}")
    typer.echo(f"cameras written to {out_dir}; score them with: v3d jac {annotations} {out_dir}")
