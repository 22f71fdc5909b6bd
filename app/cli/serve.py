"""``v3d serve``: migrate the database, optionally load the built-in demo, and run the web app.

Registered on :data:`app.cli._root.cli`. The database is ``V3D_DATABASE_URL`` (default: the SQLite
file ``var/v3d.sqlite3`` of the checkout, whose folder is created). With ``--demo`` and a database
that holds no game, the demo dataset (:func:`app.demo.generate_demo_dataset`) is written beside the
SQLite file (``var/demo/``) and imported as a SoccerNet-v3 tree before the server starts, and the demo
account (``demo`` / ``demo``, role admin, flagged as a demo) is made unless it exists; the console says
how to log in. The demo account never faces a network: ``--demo`` with a host other than a loopback
address is refused (exit 2), and so is ``--demo`` behind a declared reverse proxy (``V3D_TRUSTED_PROXIES``) and
any non-loopback host while an enabled demo account exists in the database; the demo account's login (and the
login page's hint) answers only requests made on this machine without a proxy
(``app.services.accounts.throttle.from_this_machine``), which covers a proxy left undeclared. Systems stored by an older
version of the derived rows (doubts, queue figures) are recomputed first.

``--workers N`` (N > 1) serves with N uvicorn worker processes: the start-up work above runs once, in
this process, before any worker starts; each worker then builds the app with the factory
:data:`APP_FACTORY` from the same environment (``V3D_*``). The workers share the database: write
transactions wait their turn (``app.db.session.begin_write``), so N workers behave like one process. Their metrics
are kept in the files of ``PROMETHEUS_MULTIPROC_DIR`` (a temporary folder unless set; ``app.core.metrics``). Every
process serves with :func:`server_options` (the bounds of a request's head and of idle connections).
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Optional

import typer

from app.cli._root import cli
from app.cli.errors import fail
from app.cli.remote import refuse_remote
from app.core.config import Settings, get_settings, var_dir
from app.services.accounts.throttle import is_loopback

#: What uvicorn's worker processes import and call to build the app (settings from the environment).
APP_FACTORY = "app.main:create_app"


def server_options(settings: Settings) -> dict[str, Any]:
    """uvicorn's options that bound each connection at the server's edge, for every way v3d is served (one process,
    ``--workers N``, the Docker image): the h11 implementation, whose parser refuses a request line and headers of
    more than ``V3D_MAX_HEADER_KB`` together (400, the connection closed) as soon as that much has arrived (the
    httptools parser has no such bound: one header of 80 MB sent in 1 MB pieces held the event loop for seconds), and
    the keep-alive timeout (``V3D_KEEP_ALIVE_S``). The header count and the send timeout are the app's
    (``app.api.edge``)."""
    return {"http": "h11", "h11_max_incomplete_event_size": int(settings.max_header_kb * 1024),
            "timeout_keep_alive": settings.keep_alive_s}


def demo_dir(settings: Settings) -> Path:
    """Where the demo dataset is written: ``demo/`` beside a SQLite database file, else ``var/demo``."""
    return var_dir(settings, "demo")


def load_demo_if_empty(settings: Settings) -> str:
    """Generate and import the demo dataset when the (migrated) database holds no game.

    Returns:
        A one-line account of what happened, for the console.
    """
    from app.db.session import make_engine, make_session_factory
    from app.demo import generate_demo_dataset
    from app.services.curation.queue import has_games
    from app.services.transfer.importing import import_soccernet_v3

    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            if has_games(session):
                return "demo: the database already holds games; nothing loaded"
            dataset = generate_demo_dataset(demo_dir(settings))
            report = import_soccernet_v3(session, dataset, settings)
    finally:
        engine.dispose()
    return (f"demo: imported {report.systems} systems ({report.frames} frames) from {dataset}; "
            f"{report.triangulated} triangulated")


def refresh_derived(settings: Settings) -> str | None:
    """Recompute the systems stored by an older version of the derived rows (after a schema upgrade:
    doubts and queue figures), so that everything served is current, and count those computed with other
    settings (a changed ``V3D_PROFILE``: stale until ``v3d recompute``, which may take long, so not done here).
    Returns lines for the console, None when nothing was stale."""
    from app.db.session import make_engine, make_session_factory
    from app.services.derivation.recompute import refresh_stale_systems, systems_computed_otherwise

    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            n = refresh_stale_systems(session, settings)
            otherwise = systems_computed_otherwise(session, settings)
    finally:
        engine.dispose()
    lines = [f"recomputed {n} system(s) stored by an older version (doubts and queue figures)"] if n else []
    if otherwise:
        lines.append(f"{otherwise} system(s) were computed with other settings (V3D_PROFILE={settings.profile}, "
                     "the triangulation, box and admission settings): their results are stale until `v3d recompute`")
    return "\n".join(lines) or None


def ensure_demo_account(settings: Settings) -> str:
    """Make the demo account unless it exists (``app.services.accounts.users.ensure_demo_account``); returns
    the console line saying how to log in."""
    from app.db.session import make_engine, make_session_factory
    from app.services.accounts.users import ensure_demo_account as ensure

    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            return ensure(session)
    finally:
        engine.dispose()


def demo_account_name(settings: Settings) -> Optional[str]:
    """The name of the enabled demo account of the (migrated) database, or None."""
    from app.db.session import make_engine, make_session_factory
    from app.services.accounts.users import demo_account

    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            user = demo_account(session)
            return None if user is None else user.name
    finally:
        engine.dispose()


def store_warning(settings: Settings) -> str | None:
    """A warning naming the file store (``V3D_STORAGE_URL``) when one request to it fails (unreachable, refusing v3d's
    credentials, no such bucket, no answer in time); None when it answers. The server starts all the same: what
    needs no file serves, what needs one answers 503 in these words until the store can be used."""
    from app.services.storage import storage_for
    from app.services.storage.stores import StorageError

    try:
        storage_for(settings).check_reachable()
    except StorageError as exc:
        return f"v3d: warning: {exc}; requests that need a kept file answer 503 until it can be used"
    return None


@cli.command("serve")
def serve(
    host: Annotated[str, typer.Option(help="Interface to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=1, max=65535, help="TCP port.")] = 8000,
    demo: Annotated[bool, typer.Option("--demo", help="Load the built-in demo when the database has no game, and "
                                                      "make the demo account (demo / demo, admin).")] = False,
    workers: Annotated[int, typer.Option(min=1, max=64, help="Server processes (uvicorn workers) sharing the "
                                         "database; start-up work runs once, before they start.")] = 1,
) -> None:
    """Migrate the database, load the demo if asked, and serve the review UI and the REST API (with
    ``--workers N``, N processes built by :data:`APP_FACTORY` from the same ``V3D_*`` environment)."""
    import uvicorn

    from app.core.metrics import prepare_multiprocess_dir
    from app.db.session import RestoreUnfinished, upgrade_database
    from app.main import create_app

    if not is_loopback(host):
        if demo:
            raise fail(f"--demo on {host!r}: the demo account (demo / demo, admin) has a public password and "
                       "must never face a network. Serve on 127.0.0.1 to try v3d, or create a real admin "
                       "(`v3d users add NAME --role admin`) and serve without --demo.")
    refuse_remote()  # a server is served here, never through another
    settings = get_settings()
    if demo and settings.trusted_proxies:
        raise fail("--demo with V3D_TRUSTED_PROXIES set: a reverse proxy forwards the network to this server, and the "
                   "demo account (demo / demo, admin) has a public password and must never face a network. Unset "
                   "V3D_TRUSTED_PROXIES to try v3d on this machine, or create a real admin "
                   "(`v3d users add NAME --role admin`) and serve without --demo.")
    try:
        upgrade_database(settings.database_url)
    except RestoreUnfinished as exc:  # half a backup is never served
        raise fail(str(exc)) from None
    if not is_loopback(host):
        exposed = demo_account_name(settings)
        if exposed is not None:
            raise fail(f"the demo account {exposed!r} (public password, admin) is enabled in this database and "
                       f"must never face a network: end it with `v3d users disable {exposed}` before serving "
                       f"on {host!r}.")
    refreshed = refresh_derived(settings)
    if refreshed:
        typer.echo(refreshed)
    store = store_warning(settings)
    if store:
        typer.echo(store, err=True)
    if demo:
        typer.echo(load_demo_if_empty(settings))
        typer.echo(ensure_demo_account(settings))
    typer.echo(f"v3d: review UI at http://{host}:{port}/  (API docs at http://{host}:{port}/docs)")
    typer.echo(f"v3d: log in at http://{host}:{port}/login; add users with `v3d users add NAME --role admin`")
    if not is_loopback(host):  # app.api.hosts: any other Host header gets 400 (DNS rebinding)
        named = ", ".join(settings.allowed_hosts) or "none: set V3D_ALLOWED_HOSTS to the name other machines use"
        typer.echo(f"v3d: reachable as localhost, 127.0.0.1 and [::1], and as V3D_ALLOWED_HOSTS ({named}); "
                   "requests naming another host get 400")
    if workers > 1:  # each worker process builds its own app (and engine) from the environment
        typer.echo(f"v3d: {workers} worker processes")
        # the workers count in files of one folder, summed by whichever answers GET /metrics (app.core.metrics)
        prepare_multiprocess_dir()
        uvicorn.run(APP_FACTORY, factory=True, host=host, port=port, workers=workers, **server_options(settings))
    else:
        uvicorn.run(create_app(settings), host=host, port=port, **server_options(settings))
