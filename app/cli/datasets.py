"""``v3d import ...`` and ``v3d export ...``: thin wrappers over ``app.services.transfer.importing`` and
``app.services.transfer.exporting`` (registered on :data:`app.cli._root.import_cli` / ``export_cli``).

The database is ``V3D_DATABASE_URL`` (or ``--database-url``); it is migrated to the latest schema
before use. An import is a background job (``app.services.jobs.runner``) that the command creates already
claimed and runs in its own process, drawing its progress (tqdm bars per stage); killed, the same
command run again resumes that job (imports are idempotent). A dataset error prints
``Error: <file>: <field>: <problem>`` and exits with status 2, leaving the database unchanged, as does an import of
games stored already without ``--merge keep-newer|overwrite`` (naming them); any other failure of the job exits
with status 1 and its message.
"""
from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Callable, Iterator, Literal, Optional, TypeVar

import typer

from app.cli._root import export_cli, import_cli
from app.cli.bars import StageBars
from app.cli.errors import fail
from app.cli.remote import export_tree, refuse_remote, remote_client, upload_and_wait
from app.core.config import Settings, get_settings
from app.core.errors import InvalidInputError
from app.services.exports.formats import export_format
from app.services.jobs.work import import_params
from app.services.transfer.merging import MERGE_MODES

DatabaseOpt = Annotated[Optional[str],
                        typer.Option("--database-url", help="SQLAlchemy URL (default: V3D_DATABASE_URL).")]
WorkersOpt = Annotated[Optional[int], typer.Option("--workers", min=0, help="Calibration processes (0 = all cores).")]
if TYPE_CHECKING:  # mypy cannot build a Literal from values computed at import
    MergeMode = str
else:
    MergeMode = Literal[tuple(MERGE_MODES)]
MergeOpt = Annotated[Optional[MergeMode], typer.Option(
    "--merge",
    help="Games stored already: how to merge them (without it, an import of a stored game exits 2 naming them). "
         + "; ".join(f"{mode}: {what}" for mode, what in MERGE_MODES.items()) + ".")]
_Command = TypeVar("_Command", bound=Callable[..., Any])


def export_command(name: str) -> Callable[[_Command], _Command]:
    """Register the decorated function as ``v3d export <name>``, its help the registry's description of the format
    (``app.services.exports.formats``: what each export writes is said once, for the CLI and the docs).

    Raises:
        ValueError: ``name`` is no registered export format.
    """
    return export_cli.command(name, help=export_format(name).describes)


def cli_settings(database_url: str | None, workers: int | None) -> Settings:
    """The environment's settings with the command's ``--database-url`` and ``--workers`` applied. Every command on
    the local database starts here: with ``--server`` named, one that does not run remotely ends (exit 2) saying
    which do (``app.cli.remote.refuse_remote``)."""
    refuse_remote()
    updates: dict[str, Any] = {}
    if database_url:
        updates["database_url"] = database_url
    if workers is not None:
        updates["calibration_workers"] = workers
    return get_settings().model_copy(update=updates)


@contextmanager
def session_factory(settings: Settings) -> Iterator[Any]:
    """A session factory on ``settings.database_url``, migrated to the latest schema first; the engine
    is disposed on exit."""
    from app.db.session import RestoreUnfinished, make_engine, make_session_factory, upgrade_database

    try:
        upgrade_database(settings.database_url)
    except RestoreUnfinished as exc:  # half a backup: no command reads or writes it
        raise fail(str(exc)) from None
    engine = make_engine(settings.database_url)
    try:
        yield make_session_factory(engine)
    finally:
        engine.dispose()


@contextmanager
def database_session(settings: Settings) -> Iterator[Any]:
    """A session on ``settings.database_url``, migrated to the latest schema first; the engine is
    disposed on exit."""
    with session_factory(settings) as factory, factory() as session:
        yield session


def run_job_here(settings: Settings, kind: str, params: dict[str, Any]) -> tuple[int, dict[str, Any]]:
    """Run a job of ``kind`` with ``params`` in this process, drawing its progress (tqdm bars per stage);
    resume the same job when an earlier run was killed (``jobs.find_resumable``). Returns ``(job id,
    result)``; exits 2 with the job's message when its input is invalid (a dataset that cannot be imported:
    nothing of it stored), 1 for any other failure."""
    from app.db.models import JobState
    from app.services.jobs import runner as jobs

    bars = StageBars()
    owner = jobs.owner_name(settings)
    with session_factory(settings) as factory:
        with factory() as session:
            job = jobs.find_resumable(session, kind, params, settings)
            if job is not None and jobs.claim(session, job, owner):
                typer.echo(f"resuming {kind} job {job.id}, left unfinished by {job.owner}", err=True)
            else:
                job = jobs.submit(session, kind, params, owner=owner)
            job_id = job.id
        try:
            final = jobs.run_job(factory, job_id, settings, owner, progress=bars, command_line=True)
        finally:
            bars.close()
    if final.state is not JobState.DONE:
        raise fail(str(final.message), 2 if (final.result or {}).get("invalid_input") else 1)
    return job_id, final.result or {}


def _run_import(settings: Settings, params: dict[str, Any]) -> None:
    """Run the import job of ``params`` here (:func:`run_job_here`) and print its counts."""
    print_import(*run_job_here(settings, "import", params))


def print_import(job_id: int, r: dict[str, Any]) -> None:
    """Print the counts of the import job ``job_id`` (its result ``r``), run here or on a server."""
    typer.echo(f"imported {r['source']}: {r['games']} game(s), {r['systems']} system(s), {r['frames']} frame(s) "
               f"({r['systems_new']} new, {r['systems_changed']} changed) in {r['seconds']:.1f} s (job {job_id})")
    typer.echo(f"calibrated {r['calibrated']} ({r['rig_assisted']} with the game's camera rig, "
               f"{r.get('prior_fitted', 0)} with the dataset's learned camera prior, {r.get('player_assisted', 0)} "
               f"placed by their players), refused "
               f"{r['refused']}; triangulated {r['triangulated']} system(s)")
    for reason, n in r["refusal_kinds"].items():
        typer.echo(f"  refused x{n}: {reason}")
    if r.get("players_dropped"):
        typer.echo(f"  {r['players_dropped']} player box(es) beyond V3D_MAX_PLAYERS_PER_FRAME a frame, not stored")
    for skipped in r.get("skipped_systems", []):
        typer.echo(f"  system left out: {skipped}")
    for skipped in r.get("skipped_games", []):
        typer.echo(f"  game left out: {skipped}")
    if r.get("systems_merged") or r.get("decisions_from_file") or r.get("decisions_reset"):
        typer.echo(f"merged {r['systems_merged']} stored system(s) (one audit entry each); "
                   f"{r['decisions_from_file']} decision(s) taken from the file, {r['decisions_reset']} system(s) "
                   "set back to pending")


@import_cli.command("soccernet-v3")
def import_soccernet_v3_cmd(
    path: Annotated[Path, typer.Argument(help="A SoccerNet-v3 tree (<league>/<season>/<game>/Labels-v3.json), or with "
                                              "--server a zip of one.")],
    database_url: DatabaseOpt = None,
    workers: WorkersOpt = None,
    merge: MergeOpt = None,
) -> None:
    """Import a SoccerNet-v3 tree: calibrate every frame, triangulate every system. With --server: the folder (or a
    zip of it) is uploaded and imported there."""
    with remote_client() as client:
        if client is not None:
            job = upload_and_wait(client, path, "soccernet-v3", merge=merge)
            print_import(job.id, job.result or {})
            return
    settings = cli_settings(database_url, workers)
    _run_import(settings, import_params("soccernet-v3", path, calibration_workers=workers, merge=merge))


@import_cli.command("soccernet-v3d")
def import_soccernet_v3d_cmd(
    path: Annotated[Path, typer.Argument(help="A SoccerNet-v3D tree (SNv3D.csv at its root).")],
    database_url: DatabaseOpt = None,
    merge: MergeOpt = None,
) -> None:
    """Import a SoccerNet-v3D export: cameras as given, balls from SNv3D.csv, systems re-triangulated."""
    settings = cli_settings(database_url, None)
    _run_import(settings, import_params("soccernet-v3d", path, merge=merge))


@import_cli.command("sn-calibration")
def import_sn_calibration_cmd(
    path: Annotated[Path, typer.Argument(help="A folder or zip of SoccerNet-calibration per-frame JSON.")],
    width: Annotated[Optional[int], typer.Option(help="Image width in pixels (else read from the images).")] = None,
    height: Annotated[Optional[int], typer.Option(help="Image height in pixels (else read from the images).")] = None,
    database_url: DatabaseOpt = None,
    workers: WorkersOpt = None,
    merge: MergeOpt = None,
) -> None:
    """Import a SoccerNet-calibration set: each frame becomes a single-view system to review."""
    settings = cli_settings(database_url, workers)
    _run_import(settings, import_params("sn-calibration", path, width=width, height=height,
                                        calibration_workers=workers, merge=merge))


@import_cli.command("issia")
def import_issia_cmd(
    path: Annotated[Path, typer.Argument(help="An ISSIA folder (ball_points.csv, issia_calibration.json and/or "
                                              "issia_lines.json, optional videos/ or frames/).")],
    from_lines: Annotated[bool, typer.Option("--from-lines", help="Calibrate each camera from issia_lines.json "
                                                                  "even when issia_calibration.json is present."
                                             )] = False,
    flip: Annotated[str, typer.Option(help="Comma-separated camera ids whose footage is mirrored, e.g. 1,2.")] = "",
    database_url: DatabaseOpt = None,
    merge: MergeOpt = None,
) -> None:
    """Import an ISSIA sequence: one system per frame index, static cameras calibrated once, the
    ball's trajectory fitted over the sequence."""
    settings = cli_settings(database_url, None)
    flipped = [c.strip() for c in flip.split(",") if c.strip()]
    _run_import(settings, import_params("issia", path, from_lines=from_lines, flip=flipped, merge=merge))


@import_cli.command("split")
def import_split_cmd(
    path: Annotated[Path, typer.Argument(help="A list of images, one <league>/<season>/<match>/<image> a line "
                                              "(the released SNv3D-train.txt / SNv3D-test.txt).")],
    set_name: Annotated[str, typer.Option("--set", help="The split these images form: train or test.")],
    database_url: DatabaseOpt = None,
) -> None:
    """Make the listed images the train or test split that exports and benchmarks use; lines naming no stored
    image are reported."""
    from app.services.transfer.splits import import_split

    settings = cli_settings(database_url, None)
    try:
        with database_session(settings) as session:
            report = import_split(session, path, set_name)
    except InvalidInputError as exc:  # DatasetError included: the file cannot be read
        raise fail(str(exc)) from None
    typer.echo(f"{report.frames} image(s) of {report.lines} line(s) are now in {report.set} "
               f"({report.changed} changed); {len(report.unknown)} line(s) name no stored image")
    for line in report.unknown[:20]:
        typer.echo(f"  unknown: {line}")
    if len(report.unknown) > 20:
        typer.echo(f"  ... and {len(report.unknown) - 20} more")


@import_cli.command("precise-boxes")
def import_precise_boxes_cmd(
    path: Annotated[Path, typer.Argument(help="A CSV league,season,match,image,x1,y1,x2,y2 (pixels of that image).")],
    database_url: DatabaseOpt = None,
) -> None:
    """Store precise ball boxes per view (the paper's Table 1; ``v3d evaluate boxes``); a row naming an unknown
    game or image stores nothing."""
    from app.services.evaluation.boxes import store_precise_boxes

    settings = cli_settings(database_url, None)
    try:
        with database_session(settings) as session:
            n = store_precise_boxes(session, path)
    except InvalidInputError as exc:
        raise fail(str(exc)) from None
    typer.echo(f"stored {n} precise box(es)")


@export_command("issia-3d")
def export_issia3d_cmd(
    out_dir: Annotated[Path, typer.Argument(help="Destination folder (created if missing).")],
    include_all: Annotated[bool, typer.Option("--all", help="Export every frame, not only accepted ones.")] = False,
    database_url: DatabaseOpt = None,
) -> None:
    """``v3d export issia-3d`` into ``out_dir`` (its help: the registry's description of the format)."""
    if exported_remotely("issia-3d", out_dir, include_all, True, None):
        return
    from app.services.issia.export import export_issia3d

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        report = export_issia3d(session, out_dir, include_all=include_all)
    typer.echo(f"exported {report.rows} frame row(s) of {report.sequences} sequence(s) to {report.out_dir} "
               f"(cameras 3-6 train, 1-2 test: split.json; {report.calibrations} camera calibration(s))")


@export_command("soccernet-v3d")
def export_soccernet_v3d_cmd(
    out_dir: Annotated[Path, typer.Argument(help="Destination folder (created if missing).")],
    include_all: Annotated[bool, typer.Option("--all", help="Export every system, not only accepted ones.")] = False,
    no_images: Annotated[bool, typer.Option("--no-images", help="Leave out each game's Frames-v3.zip "
                                                                "(the images).")] = False,
    release: Annotated[Optional[str], typer.Option("--release", help="Export this release (its accepted systems as "
                                                   "they were when it was made) instead of the database now; the "
                                                   "folder then holds the zip's files: the same every time.")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """``v3d export soccernet-v3d`` into ``out_dir`` (its help: the registry's description of the format)."""
    if exported_remotely("soccernet-v3d", out_dir, include_all, not no_images, release):
        return
    from app.services.images.serving import ImageUnavailable
    from app.services.transfer.exporting import export_soccernet_v3d

    settings = cli_settings(database_url, None)
    if release is not None:
        written = release_tree(settings, out_dir, release, include_all, not no_images)
        typer.echo(f"exported release {release} ({written['hash']}): {written['systems']} system(s), "
                   f"{written['views']} view(s) to {out_dir}")
        return
    bars = StageBars()
    try:
        with database_session(settings) as session:
            report = export_soccernet_v3d(session, out_dir, include_all=include_all, progress=bars,
                                          images=not no_images)
    except (InvalidInputError, ImageUnavailable) as exc:
        raise fail(str(exc)) from None
    finally:
        bars.close()
    typer.echo(f"exported {report.systems} system(s) of {report.games} game(s), {report.rows} row(s) "
               f"and {report.images} image(s) to {report.out_dir} ({report.csv_path.name})")


def exported_remotely(fmt: str, out_dir: Path, include_all: bool, images: bool, release: str | None) -> bool:
    """With ``--server``: the export ``fmt`` run there and unpacked under ``out_dir`` (``app.cli.remote.export_tree``),
    its counts printed; True then, False without a server (the command runs locally). ``--all`` beside ``--release``
    ends the command (exit 2), as locally."""
    with remote_client() as client:
        if client is None:
            return False
        if release is not None and include_all:
            raise fail("--all and --release exclude each other (a release holds its accepted systems)")
        written = export_tree(client, fmt, out_dir, include_all, images, release)
    of = f" of release {release}" if release is not None else ""
    typer.echo(f"exported {fmt}{of} to {out_dir}: {json.dumps(written, sort_keys=True)}")
    return True


def release_tree(settings: Settings, out_dir: Path, release: str, include_all: bool, images: bool,
                 fmt: str = "soccernet-v3d") -> dict[str, Any]:
    """``v3d export FORMAT OUT_DIR --release NAME``: the release's export ``fmt`` as a zip (as an export job writes
    it) unpacked under ``out_dir``; its counts. ``--all`` beside ``--release``, an unknown release, or an image that
    cannot be read end the command with the error and exit status 2."""
    if include_all:
        raise fail("--all and --release exclude each other (a release holds its accepted systems)")
    return zip_tree(settings, out_dir, fmt, False, images, release)


def zip_tree(settings: Settings, out_dir: Path, fmt: str, include_all: bool, images: bool,
             release: str | None) -> dict[str, Any]:
    """The export ``fmt`` as a zip, as an export job writes it (of the database now, every system with
    ``include_all``, or of ``release``), unpacked under ``out_dir``; its counts. An unknown release, a bad input or an
    image that cannot be read end the command with the error and exit status 2."""
    # imported here, as the other commands' services: ``v3d --help`` loads none of them
    import tempfile
    import zipfile

    from app.core.errors import NotFoundError
    from app.services.exports.files import write_export_zip
    from app.services.images.serving import ImageUnavailable

    try:
        with database_session(settings) as session, tempfile.TemporaryDirectory(prefix="v3d-release-") as tmp:
            target = Path(tmp) / "release.zip"
            report = write_export_zip(session, fmt, target, include_all, settings, images=images, release=release)
            out_dir.mkdir(parents=True, exist_ok=True)
            with zipfile.ZipFile(target) as zf:
                zf.extractall(out_dir)  # member names are checked folder names (exporting.safe_component)
    except (InvalidInputError, ImageUnavailable, NotFoundError) as exc:
        raise fail(str(exc)) from None
    return report


@export_command("cameras")
def export_cameras_cmd(
    out_dir: Annotated[Path, typer.Argument(help="Destination folder (created if missing).")],
    include_all: Annotated[bool, typer.Option("--all", help="Export every system, not only accepted ones.")] = False,
    release: Annotated[Optional[str], typer.Option("--release", help="Export this release's cameras instead of the "
                                                   "database now (the same files every time).")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """``v3d export cameras`` into ``out_dir`` (its help: the registry's description of the format)."""
    if exported_remotely("cameras", out_dir, include_all, False, release):
        return
    from app.services.transfer.cameras_export import export_cameras

    settings = cli_settings(database_url, None)
    if release is not None:
        written = release_tree(settings, out_dir, release, include_all, False, "cameras")
        typer.echo(f"exported release {release} ({written['hash']}): {written['cameras']} camera(s) to {out_dir}")
        return
    try:
        with database_session(settings) as session:
            report = export_cameras(session, out_dir, include_all=include_all)
    except InvalidInputError as exc:
        raise fail(str(exc)) from None
    kinds = ", ".join(f"{n} {k}" for k, n in sorted(report.by_kind.items())) or "none"
    sizes = ", ".join(f"{s}: {n} view(s)" for s, n in report.sizes.items()) or "no view"
    typer.echo(f"exported {report.cameras} camera(s) to {report.out_dir} ({kinds}; {sizes}; "
               f"{report.ground_truth} ground-truth file(s))")
