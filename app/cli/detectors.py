"""``v3d export yolo|coco`` and ``v3d evaluate monocular|sensitivity``: detector data and the monocular
3D ball benchmark (thin wrappers over ``app.services.transfer.detector_export``, ``app.services.evaluation.monocular``
and ``app.services.evaluation.plots``). A bad input prints ``Error: ...`` and exits with status 2.
"""
from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path
from typing import Annotated, Optional

import typer

from app.cli._root import cli
from app.cli.datasets import (
    DatabaseOpt,
    cli_settings,
    database_session,
    export_command,
    exported_remotely,
    release_tree,
)
from app.cli.errors import fail
from app.cli.remote import remote_client
from app.core.errors import DatasetError, InvalidInputError
from app.datasets.csv_cells import inert_cell

evaluate_cli = typer.Typer(help="Evaluate detectors against the curated labels.", no_args_is_help=True)
cli.add_typer(evaluate_cli, name="evaluate")

AllOpt = Annotated[bool, typer.Option("--all", help="Every system, not only the accepted ones.")]
ReleaseOpt = Annotated[Optional[str], typer.Option("--release", help="Export this release instead of the database now "
                                                   "(the same files every time).")]


def _export(fmt: str, out_dir: Path, include_all: bool, database_url: str | None, release: str | None = None) -> None:
    if exported_remotely(fmt, out_dir, include_all, True, release):
        return
    from app.services.transfer.detector_export import export_detector

    settings = cli_settings(database_url, None)
    if release is not None:
        written = release_tree(settings, out_dir, release, include_all, False, fmt)
        typer.echo(f"exported {fmt} of release {release} ({written['hash']}) to {out_dir}: "
                   + ", ".join(f"{s}: {n} image(s)" for s, n in written["images"].items()))
        return
    with database_session(settings) as session:
        report = export_detector(session, fmt, out_dir, include_all, settings.ball_diameter_m,  # type: ignore[arg-type]  # typer checked fmt against the two formats
                                 settings.export_ball_box)
    per_split = ", ".join(f"{s}: {report.images[s]} image(s), {report.ball_boxes[s]} ball box(es), "
                          f"{report.other_boxes[s]} other box(es)" for s in report.images)
    typer.echo(f"exported {fmt} to {report.out_dir}: {per_split}")
    typer.echo(f"ball boxes refined: {report.refined_ball_boxes}, optimised: {report.optimised_ball_boxes}; skipped "
               f"{report.skipped_without_image} view(s) without an image, {report.skipped_point_only} with a "
               "point-only ball")
    for split in report.empty_splits:
        typer.echo(f"split {split!r} has no image (its folders exist, empty)")
    for cls, n in report.unknown_classes.items():
        typer.echo(f"  skipped x{n} box(es) of unknown class {cls!r}")


@export_command("yolo")
def export_yolo_cmd(
    out_dir: Annotated[Path, typer.Argument(help="Destination folder (created if missing).")],
    include_all: AllOpt = False,
    release: ReleaseOpt = None,
    database_url: DatabaseOpt = None,
) -> None:
    """``v3d export yolo`` into ``out_dir`` (its help: the registry's description of the format)."""
    _export("yolo", out_dir, include_all, database_url, release)


@export_command("coco")
def export_coco_cmd(
    out_dir: Annotated[Path, typer.Argument(help="Destination folder (created if missing).")],
    include_all: AllOpt = False,
    release: ReleaseOpt = None,
    database_url: DatabaseOpt = None,
) -> None:
    """``v3d export coco`` into ``out_dir`` (its help: the registry's description of the format)."""
    _export("coco", out_dir, include_all, database_url, release)


def _fmt(x: float | None, pattern: str) -> str:
    return "n/a" if x is None else pattern.format(x)


@evaluate_cli.command("monocular")
def evaluate_monocular_cmd(
    predictions: Annotated[Optional[Path], typer.Argument(help="A folder of YOLO txt files or a COCO results JSON "
                                                               "(or --source).")] = None,
    source: Annotated[Optional[str], typer.Option(help="Score an imported source's stored predictions (v3d import "
                                                       "predictions) instead of a file.")] = None,
    json_out: Annotated[Optional[Path], typer.Option("--json", help="Write the report as JSON here.")] = None,
    plots: Annotated[Optional[Path],
                     typer.Option("--plots", help="Write the precision curve and sensitivity plots here.")] = None,
    ball_class: Annotated[Optional[int],
                          typer.Option("--ball-class", help="Ball class (YOLO) or category id (COCO).")] = None,
    estimator: Annotated[Optional[str], typer.Option(help="'paper' (Eq. ball3Destimation) or 'exact' (sphere "
                                                   "silhouette); default: the one matching "
                                                   "V3D_OPTIMISED_BOX_METHOD.")] = None,
    cameras: Annotated[Optional[Path], typer.Option("--cameras", help="Score with these cameras instead of the stored "
                                                    "ones: a cameras export (v3d export cameras: cameras.json, "
                                                    "<W>x<H>/predictions.zip).")] = None,
    include_all: AllOpt = False,
    database_url: DatabaseOpt = None,
) -> None:
    """AP@0.5, MAE (m, %), P@2m and the precision-threshold curve of ball detections, per split."""
    from app.services.evaluation.monocular import (
        default_estimator,
        evaluate_predictions,
        evaluate_source,
        reference_views,
    )

    settings = cli_settings(database_url, None)
    estimator = estimator or default_estimator(settings.optimised_box_method)
    if (predictions is None) == (source is None) or (source is not None and cameras is not None):
        raise fail("give a predictions file or --source NAME (not both; --cameras with a file only)")
    try:
        with database_session(settings) as session:
            if source is not None:
                report = evaluate_source(session, source, include_all, settings.ball_diameter_m, estimator,
                                         settings.export_ball_box, per_frame=settings.max_predictions_per_frame)
            else:
                assert predictions is not None  # checked above
                report = evaluate_predictions(session, predictions, include_all, ball_class,
                                              settings.ball_diameter_m, estimator, cameras_dir=cameras,
                                              ball_box=settings.export_ball_box,
                                              max_coco_bytes=int(settings.max_predictions_mb * (1 << 20)),
                                              per_frame=settings.max_predictions_per_frame)
            views = (reference_views(session, include_all, settings.ball_diameter_m, settings.export_ball_box)
                     if plots else [])
    except InvalidInputError as exc:
        raise fail(str(exc)) from None
    for name, rep in [("all", report), *report["splits"].items()]:
        c = rep["counts"]
        typer.echo(f"{name:5s}  AP50 {_fmt(rep['AP50'], '{:.4f}')}  MAE {_fmt(rep['MAE_m'], '{:.3f}')} m  "
                   f"MAE {_fmt(rep['MAE_pct'], '{:.2f}')} %  P@2m {_fmt(rep['P_2m'], '{:.3f}')}  "
                   f"({c['localised']} of {c['reference_views']} views localised, {c['detections']} detections)")
    typer.echo(f"ignored {report['counts']['ignored_detections']} detection(s) in images without a 3D ball; "
               f"monocular estimator: {estimator}; cameras: {report['cameras']}"
               + (f" ({report['counts']['views_without_camera']} view(s) without one left out)" if cameras else ""))
    if json_out:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(report, indent=1))
        typer.echo(f"wrote {json_out}")
    if plots:
        from app.services.evaluation.plots import plot_precision_curve, plot_sensitivity, sensitivity_curves

        paths = plot_precision_curve(report, plots) + plot_sensitivity(
            sensitivity_curves(views, settings.ball_diameter_m, estimator=estimator), plots)
        typer.echo("wrote " + ", ".join(str(p) for p in paths))


@evaluate_cli.command("boxes")
def evaluate_boxes_cmd(
    precise: Annotated[Optional[Path], typer.Argument(help="A CSV league,season,match,image,x1,y1,x2,y2 (pixels); "
                                                           "stored first. Default: the stored precise boxes.")] = None,
    json_out: Annotated[Optional[Path], typer.Option("--json", help="Write the report as JSON here.")] = None,
    include_all: AllOpt = False,
    database_url: DatabaseOpt = None,
) -> None:
    """The paper's Table 1: IoU and size error of the original, optimised and refined ball boxes against the
    precise boxes (views of accepted systems, every system with --all)."""
    from app.services.evaluation.boxes import BOX_KINDS, evaluate_boxes, store_precise_boxes

    settings = cli_settings(database_url, None)
    try:
        with database_session(settings) as session:
            if precise is not None:
                typer.echo(f"stored {store_precise_boxes(session, precise)} precise box(es)")
            report = evaluate_boxes(session, include_all, settings.ball_diameter_m)
    except InvalidInputError as exc:
        raise fail(str(exc)) from None
    typer.echo(f"{report['views']} view(s) with a precise box")
    for k in BOX_KINDS:
        r = report[k]
        figures = "-" if not r["n"] else f"IoU {r['iou']:.3f}, size error {r['size_error_pct']:.1f} %"
        typer.echo(f"  {k:<9} n={r['n']:<5} {figures}")
    if json_out is not None:
        json_out.write_text(json.dumps(report, indent=1) + "\n")


stats_cli = typer.Typer(help="The dataset at a glance; `v3d stats annotators`: the per-annotator figures.",
                        invoke_without_command=True)
cli.add_typer(stats_cli, name="stats")


@stats_cli.callback()
def stats_cmd(
    ctx: typer.Context,
    json_out: Annotated[Optional[Path], typer.Option("--json", help="Write the statistics as JSON here.")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """The dataset at a glance: systems and images (calibrated, admitted) per kind and split, systems kept against
    the JaC admission threshold (the paper's Fig. 3) and distributions (app.services.evaluation.stats)."""
    if ctx.invoked_subcommand is not None:
        return
    from app.services.evaluation.stats import dataset_stats

    with remote_client() as client:
        stats = client.stats().model_dump(mode="json") if client is not None else None
    if stats is None:
        settings = cli_settings(database_url, None)
        with database_session(settings) as session:
            stats = dataset_stats(session, settings)
    for kind, k in stats["kinds"].items():
        typer.echo(f"{kind}: {k['systems']} system(s), {k['images']} image(s), {k['calibrated_images']} calibrated, "
                   f"{k['admitted_images']} admitted")
        for split, c in sorted(k["splits"].items()):
            typer.echo(f"  {split:<5}  {c['systems']} system(s), {c['images']} image(s), {c['calibrated_images']} "
                       f"calibrated, {c['admitted_images']} admitted")
    if stats["stale_systems"]:
        typer.echo(f"{stats['stale_systems']} system(s) were computed with other settings: stale until `v3d recompute`")
    typer.echo("3D balls by evidence: " + ", ".join(f"{n} {tier}" for tier, n in stats["ball_evidence"].items()))
    typer.echo("systems kept by JaC threshold: " + ", ".join(
        f"{r['threshold']:.2f}: {r['systems_kept']}" for r in stats["jac_sweep"][::4]))
    if json_out is not None:
        json_out.write_text(json.dumps(stats, indent=1) + "\n")
        typer.echo(f"wrote {json_out}")


@stats_cli.command("annotators")
def stats_annotators_cmd(
    since: Annotated[Optional[datetime], typer.Option(help="Only entries at or after this time (UTC).")] = None,
    until: Annotated[Optional[datetime], typer.Option(help="Only entries before this time (UTC).")] = None,
    csv_out: Annotated[Optional[Path], typer.Option("--csv", help="Write the figures as CSV here.")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """Per-person figures: label edits, systems touched and decided, needs fix received, accepted at first review,
    median time from edit to review, median distance of their ball labels from the ball the other views agree on (px
    at 1920 width) and the share a doubt accuses; as a reviewer, the decisions made (accepted, rejected, needs fix)
    and the re-reviews (app.services.evaluation.annotators)."""
    import csv

    from app.services.evaluation.annotators import FIELDS, annotator_figures

    utc = [None if t is None else t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t for t in (since, until)]
    with remote_client() as client:
        figures = ([a.model_dump() for a in client.annotators(since=utc[0], until=utc[1])] if client is not None
                   else None)
    if figures is None:
        settings = cli_settings(database_url, None)
        with database_session(settings) as session:
            figures = [f.as_dict() for f in annotator_figures(session, utc[0], utc[1])]
    if not figures:
        typer.echo("no label edits, decisions or hand-offs in this window")
    for f in figures:
        typer.echo(f"{f['name']}: {f['edits']} edit(s) on {f['systems_touched']} system(s), "
                   f"{f['systems_decided']} decided, {f['accepted_first_review']} accepted at first review, "
                   f"{f['needs_fix_received']} returned to them; median edit to review "
                   f"{_fmt(f['median_edit_to_review_s'], '{:.0f} s')}, median label distance "
                   f"{_fmt(f['median_label_distance_px'], '{:.1f} px')}, accused "
                   f"{_fmt(None if f['accused_share'] is None else 100 * f['accused_share'], '{:.0f} %')}; "
                   f"reviewed: {f['decisions']} decision(s), {f['accepted']} accepted, {f['rejected']} rejected, "
                   f"{f['needs_fix']} needs fix, {f['re_reviews']} re-review(s)")
    if csv_out is not None:
        with csv_out.open("w", newline="") as out:
            writer = csv.writer(out, lineterminator="\n")
            writer.writerow(FIELDS)
            writer.writerows([["" if f[k] is None else inert_cell(f[k]) if isinstance(f[k], str) else f[k]
                               for k in FIELDS] for f in figures])
        typer.echo(f"wrote {csv_out}")


@stats_cli.command("yield")
def stats_yield_cmd(
    truth: Annotated[Optional[Path], typer.Option("--truth", help="A synthetic set's truth JSON: count the right 3D "
                                                  "balls (within 0.5 m) too.")] = None,
    json_out: Annotated[Optional[Path], typer.Option("--json", help="Write the figures as JSON here.")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """Systems with a 3D ball under the paper's rules (JaC@0.5 % > 0.75 views only, tau, 1 m, labelled views only)
    and under v3d's (the stored 3D ball, from the labels as they are now), side by side
    (app.services.evaluation.ball_yield)."""
    from app.datasets.files import load_json_file
    from app.services.evaluation.ball_yield import ball_yield, truth_balls

    try:  # the truth's shape checked before the database is opened: a wrong file costs nothing
        given = None if truth is None else load_json_file(truth)
        if given is not None:
            truth_balls(given)
    except DatasetError as exc:  # names the file already
        raise fail(f"--truth {exc}") from None
    except ValueError as exc:
        raise fail(f"--truth {truth}: {exc}") from None
    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        report = ball_yield(session, settings, given)
    n = report["systems"]
    for rule, words in (("paper", "paper's rules (admitted views, labels only)"), ("v3d", "v3d (stored 3D ball)")):
        r = report[rule]
        right = "" if r["right"] is None else (f", {r['right']} right within {report['right_m']:g} m, {r['wrong']} "
                                               f"more than {report['wrong_m']:g} m off")
        typer.echo(f"{words}: {r['with_ball']} of {n} system(s) with a 3D ball{right}")
    if report["truth_systems"] is not None and report["truth_systems"] < n:
        typer.echo(f"{n - report['truth_systems']} system(s) not in the truth file")
    if json_out is not None:
        json_out.write_text(json.dumps(report, indent=1) + "\n")
        typer.echo(f"wrote {json_out}")


@evaluate_cli.command("sensitivity")
def evaluate_sensitivity_cmd(
    out_dir: Annotated[Path, typer.Argument(help="Folder for sensitivity.png/.svg and sensitivity.json.")],
    samples: Annotated[int, typer.Option(min=1, help="Views drawn at random (paper: 100).")] = 100,
    estimator: Annotated[Optional[str], typer.Option(help="'paper' or 'exact' (default: matching the boxes).")] = None,
    include_all: AllOpt = False,
    database_url: DatabaseOpt = None,
) -> None:
    """The paper's sensitivity study on the curated labels: box size +-10 %, centre up to 2 % of the diagonal."""
    import numpy as np

    from app.services.evaluation.monocular import default_estimator, reference_views
    from app.services.evaluation.plots import plot_sensitivity, sensitivity_curves

    settings = cli_settings(database_url, None)
    estimator = estimator or default_estimator(settings.optimised_box_method)
    with database_session(settings) as session:
        views = reference_views(session, include_all, settings.ball_diameter_m, settings.export_ball_box)
    if not views:
        raise fail("no view with a 3D ball among the selected systems (accept systems, or use --all)")
    study = sensitivity_curves(views, settings.ball_diameter_m, samples, estimator=estimator)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "sensitivity.json").write_text(json.dumps(study))
    paths = plot_sensitivity(study, out_dir)
    size10 = [max(r["size_error_m"][0], r["size_error_m"][-1]) for r in study["views"]]
    shift2 = [r["centre_error_m"][-1] for r in study["views"]]
    typer.echo(f"{len(study['views'])} views: error at +-10 % size {np.min(size10):.2f} to {np.max(size10):.2f} m "
               f"(median {np.median(size10):.2f}); at 2 % centre shift {np.min(shift2):.2f} to {np.max(shift2):.2f} m "
               f"(median {np.median(shift2):.2f})")
    typer.echo("wrote " + ", ".join(str(p) for p in paths))
