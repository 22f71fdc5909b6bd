"""The FastAPI application: ``create_app(settings)`` builds one, with its own engine and sessions.

Nothing is connected at import time. ``uvicorn --factory app.main:create_app`` serves the settings of
the environment; tests pass their own :class:`~app.core.config.Settings` pointing at a migrated
temporary database. Migrating is the caller's job (``v3d serve`` runs ``upgrade_database``), never
this factory's, so that a test database is built once by the migrations and then only used.

Besides the REST API under ``/api`` the app serves the UI pages (``/`` and ``/systems/{id}``), the
static files under ``/static`` (revalidated through their ``ETag`` on every load, so a changed module
is never served stale), and the OpenAPI docs at ``/docs`` (Swagger UI, ``static/docs.html`` started by
``static/js/docs.js``) with their JavaScript and CSS from the ``fastapi-offline`` package: no CDN. ReDoc
is not served: its bundle fetches a logo from ``cdn.redoc.ly``. Every answer carries the security
headers of ``app.api.security`` (a CSP allowing this server's own scripts only). With
``Settings.job_runner`` the app's lifespan runs a :class:`~app.services.jobs.runner.JobRunner` (queued
imports, recomputes and exports; a job a killed process left running is resumed) and sets the garbage
collector's young-generation threshold (``Settings.gc_young_threshold``). The factory sets how many recomputing edits
compute at once in this process (``app.services.curation.writing.EditSlots``, ``Settings.edit_slots``), handed to
each edit in its context (``app.api.deps.edit_context``).

Authentication (``app.api.authentication``): the session cookie middleware (its signing key read from
``V3D_SESSION_SECRET`` or the database when the middleware is built, at the first request or lifespan
start), then the middleware that resolves the principal and answers 401 / CSRF 403 under ``/api``. The
pages (``/``, ``/login``, ``/systems/{id}``), static files and the docs are public. Before both: a request
naming a ``Host`` that is neither a loopback name nor one of ``V3D_ALLOWED_HOSTS`` gets 400
(``app.api.hosts``: DNS rebinding), and a body is bounded by its route (``app.api.bodies``: 415 for a type the
route does not take, 413 beyond its limit). Outermost of all (``app.api.edge``): a request of too many header lines
gets 431, and every answer leaves in pieces, each within ``V3D_SEND_TIMEOUT_S`` (a client that stops reading is
disconnected). Around all of them, each request is timed for the metrics (``app.api.request_metrics``), served to
admins at ``/metrics`` in Prometheus' text format (``app.api.routes.metrics``).
"""
from __future__ import annotations

import gc
import html
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, HTTPException, Request
from fastapi.responses import FileResponse, HTMLResponse, Response
from fastapi_offline import FastAPIOffline
from sqlalchemy.pool import QueuePool
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.staticfiles import StaticFiles
from starlette.types import Scope

from app import __version__
from app.api.authentication import AuthenticationMiddleware, SessionCookieMiddleware
from app.api.bodies import BodyLimitMiddleware
from app.api.compression import CompressionMiddleware
from app.api.deps import SessionDep
from app.api.edge import EdgeMiddleware
from app.api.errors import install_error_handlers
from app.api.hosts import allowed_hosts
from app.api.main import api_router
from app.api.probe import HealthProbe
from app.api.request_metrics import RequestMetricsMiddleware
from app.api.routes import metrics
from app.api.schemas import db_id
from app.api.security import SecurityHeadersMiddleware
from app.api.share import ComputeShare
from app.core.config import Settings, get_settings
from app.core.errors import NotFoundError
from app.core.paths import STATIC_DIR
from app.db.in_use import using
from app.db.session import make_engine, make_session_factory
from app.services.accounts.throttle import login_throttle
from app.services.accounts.users import session_secret
from app.services.curation.writing import EditSlots, get_system
from app.services.jobs.runner import JobRunner

#: Where the local Swagger UI assets (from fastapi-offline) are mounted.
DOCS_ASSETS_URL = "/docs-assets"


class RevalidatedStaticFiles(StaticFiles):
    """Static files that the browser must revalidate (``Cache-Control: no-cache``) on each use.

    Starlette already answers with an ``ETag`` and turns a matching ``If-None-Match`` into 304, so a
    revalidation costs one small round trip and an edited file (ES modules imported by other modules
    included, which a hash query in the HTML could not reach) is picked up at once.
    """

    async def get_response(self, path: str, scope: Scope) -> Response:
        """Serve ``path`` like :class:`StaticFiles` and add the revalidation header."""
        response = await super().get_response(path, scope)
        response.headers.setdefault("Cache-Control", "no-cache")
        return response


def _page(name: str) -> FileResponse:
    path: Path = STATIC_DIR / name
    if not path.is_file():
        raise HTTPException(status_code=404, detail=f"UI page static/{name} is missing")
    return FileResponse(path, media_type="text/html", headers={"Cache-Control": "no-cache"})


def _missing_system_page(system_id: str, query: str) -> HTMLResponse:
    """404 for a person following a stale link to ``/systems/{id}``: a small page saying the system
    does not exist, with a link back to the queue (keeping the queue's filters of the link)."""
    name = html.escape(system_id)
    queue = html.escape(f"/?{query}" if query else "/")
    body = f"""<!doctype html>
<html lang="en">
<head>
  <meta charset="utf-8">
  <meta name="viewport" content="width=device-width, initial-scale=1">
  <title>System not found · v3d review</title>
  <link rel="icon" href="data:,">
  <link rel="stylesheet" href="/static/css/app.css">
</head>
<body>
  <main style="max-width: 40rem; margin: 48px auto; padding: 0 16px"><div class="card" data-testid="system-missing">
    <h1>System not found</h1>
    <p>System <span class="mono">{name}</span> does not exist: it may have been removed or re-imported
    under a new id, or the link is wrong.</p>
    <p><a href="{queue}" data-testid="queue-link">Back to the review queue</a></p>
  </div></main>
</body>
</html>
"""
    return HTMLResponse(body, status_code=404, headers={"Cache-Control": "no-cache"})


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the v3d web application.

    Args:
        settings: configuration; ``None`` reads the environment (:func:`get_settings`). The database
            at ``settings.database_url`` must already be migrated.

    Returns:
        The FastAPI app. Its engine is disposed of when the app's lifespan ends.
    """
    settings = settings or get_settings()
    engine = make_engine(settings.database_url, write_lock_timeout_s=settings.write_lock_timeout_s)
    # the health probe's own connection: it never waits for the request pool (app.api.routes.health)
    health_engine = make_engine(settings.database_url, poolclass=QueuePool, pool_size=1, max_overflow=0)

    @asynccontextmanager
    async def lifespan(application: FastAPI) -> AsyncIterator[None]:
        if settings.gc_young_threshold:  # a served process: rarer full collections (Settings.gc_young_threshold)
            gc.set_threshold(settings.gc_young_threshold, 10, 10)
        # the database's shared in-use lock, for as long as this process serves: `v3d restore` refuses while it is
        # held (app.db.in_use), and a restore running now refuses this start
        with using(settings.database_url, "server"):
            runner = None
            if settings.job_runner:  # queued imports, recomputes and exports run in a thread of this process
                runner = JobRunner(application.state.session_factory, settings)
                runner.start()
            application.state.job_runner = runner
            yield
            if runner is not None:
                runner.stop()
        engine.dispose()
        health_engine.dispose()

    app = FastAPIOffline(
        title="v3d",
        summary="Multi-view soccer broadcast annotations to reviewed 3D ball labels (SoccerNet-v3D).",
        version=__version__,
        lifespan=lifespan,
        static_url=DOCS_ASSETS_URL,
        # ReDoc's bundle loads its footer logo from cdn.redoc.ly: Swagger UI alone is served. The docs
        # page is ours (static/docs.html): its start-up script is a served file, as the CSP requires.
        redoc_url=None,
        docs_url=None,
    )
    app.state.settings = settings
    app.state.session_factory = make_session_factory(engine)
    app.state.health_probe = HealthProbe(health_engine)
    # This process's turns of the recomputing edits (Settings.edit_slots), handed to each edit (app.api.deps)
    app.state.edit_slots = EditSlots(settings.edit_slots, settings.edit_slot_wait_s)
    # Each user's share of the process's previews and evaluations (Settings.compute_share, app.api.share)
    app.state.compute_share = ComputeShare(settings.compute_share)
    # Failed logins counted in the database, through the app's session factory of the moment (tests swap it).
    app.state.login_throttle = login_throttle(settings, lambda: app.state.session_factory())

    _add_middleware(app, settings)

    install_error_handlers(app)
    app.include_router(api_router, prefix="/api")
    app.include_router(metrics.router)  # GET /metrics: beside /api, as Prometheus expects it
    app.mount("/static", RevalidatedStaticFiles(directory=STATIC_DIR, check_dir=False), name="static")

    _add_pages(app)
    return app


def _add_middleware(app: FastAPI, settings: Settings) -> None:
    """The app's middleware, from the edge inwards: header count and send timeout, security headers, the Host check,
    the session cookie, the authentication, the body limits, the compression of answers."""

    def secret() -> str:
        override = settings.session_secret.get_secret_value() if settings.session_secret else None
        with app.state.session_factory() as session:
            return session_secret(session, override)

    # Added innermost first: security headers around the Host check around the session cookie around the
    # authentication around the body limits. A request naming a foreign Host is refused before anything looks at
    # it; an anonymous request to a protected route gets its 401 without a byte of its body read; a body of a type
    # its route does not take, or too large, is refused before the route reads it. The compression of answers is
    # innermost (app.api.compression: never an answer carrying a secret).
    app.add_middleware(CompressionMiddleware)
    app.add_middleware(BodyLimitMiddleware, routes=app.router.routes, settings=settings)
    app.add_middleware(AuthenticationMiddleware, max_age_s=settings.session_max_age_s)
    app.add_middleware(SessionCookieMiddleware, secret=secret, max_age=settings.session_max_age_s,
                       https_only=settings.secure_cookies)
    app.add_middleware(TrustedHostMiddleware, allowed_hosts=allowed_hosts(settings), www_redirect=False)
    app.add_middleware(SecurityHeadersMiddleware)
    # Outermost: too many header lines are refused first; every answer leaves in pieces, each within the send timeout
    app.add_middleware(EdgeMiddleware, max_headers=settings.max_header_count, send_timeout_s=settings.send_timeout_s)
    # Around everything: each request's time to its last byte, by route template and status (app.core.metrics)
    app.add_middleware(RequestMetricsMiddleware, routes=app.router.routes)


def _add_pages(app: FastAPI) -> None:
    """The HTML pages beside the API (``static/``): the docs, the queue, the login and a system's page."""
    @app.api_route("/docs", methods=["GET", "HEAD"], include_in_schema=False)
    def docs_page() -> FileResponse:
        """The offline API docs (Swagger UI from fastapi-offline's assets, started by static/js/docs.js)."""
        return _page("docs.html")

    @app.api_route("/", methods=["GET", "HEAD"], include_in_schema=False)
    def queue_page() -> FileResponse:
        """The review queue (``static/index.html``)."""
        return _page("index.html")

    @app.api_route("/login", methods=["GET", "HEAD"], include_in_schema=False)
    def login_page() -> FileResponse:
        """The login page (``static/login.html``; ``?next=`` is where it goes after the login)."""
        return _page("login.html")

    @app.api_route("/systems/{system_id}", methods=["GET", "HEAD"], include_in_schema=False)
    def system_page(request: Request, session: SessionDep, system_id: str) -> Response:
        """One multi-view system (``static/system.html``); for an id that names no system, a small
        HTML page saying so with a link back to the queue (404; ``/api`` routes keep answering JSON).
        Anonymous visitors get the page without the look-up (it sends them to log in; nothing is said
        about which systems exist)."""
        if getattr(request.state, "principal", None) is None:
            return _page("system.html")
        try:
            wanted = db_id(system_id)  # the API's id type: no row has an id beyond the database's integers
            if wanted is None:
                raise NotFoundError("system", system_id)
            get_system(session, wanted)
        except NotFoundError:
            return _missing_system_page(system_id, request.url.query)
        return _page("system.html")
