"""The request metrics' middleware: each HTTP request's time to its answer's last byte, by the template of the
route that answered it (``app.core.metrics.observe_request``), so that ``/api/frames/7/ball`` and
``/api/frames/8/ball`` are one series and a scanner's random paths are none of their own."""
from __future__ import annotations

from time import perf_counter
from typing import Any

from fastapi.routing import iter_route_contexts
from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.core.metrics import UNMATCHED, observe_request


class RouteTemplates:
    """The full path template of each route of an app, prefixes of included routers included (FastAPI's router sets
    ``scope["route"]`` to the route as declared in its router, whose own ``path`` lacks them). Read when first asked:
    every route is in place by the first request. A route included under two prefixes would be named by one."""

    def __init__(self, routes: list[Any]) -> None:
        self.routes = routes
        self._contexts: list[Any] | None = None
        self._by_route: dict[int, str] = {}

    def _load(self) -> list[Any]:
        if self._contexts is None:
            contexts = list(iter_route_contexts(self.routes))
            self._by_route = {id(c.original_route): c.path for c in contexts if c.path}
            self._contexts = contexts
        return self._contexts

    def of(self, scope: Scope, status: int) -> str:
        """The template of the route that answered (``scope["route"]``), or, for an answer given before routing (a
        401, a refused Host or body), of the route the request would have reached; else (a 404 no route matched)
        :data:`UNMATCHED`. Matching the routes again costs about 0.2 ms (some 150 routes), only for those early
        answers: a 404 of no route is named without it, so that a scanner's paths cost nothing more."""
        contexts = self._load()
        route = scope.get("route")
        if route is not None:
            return self._by_route.get(id(route)) or getattr(route, "path", None) or UNMATCHED
        if status == 404:
            return UNMATCHED
        for context in contexts:
            if context.matches(scope)[0] is not Match.NONE:
                return context.path or UNMATCHED
        return UNMATCHED


class RequestMetricsMiddleware:
    """Times every HTTP request (outermost: the whole answer, every middleware included)."""

    def __init__(self, app: ASGIApp, routes: list[Any]) -> None:
        self.app, self.templates = app, RouteTemplates(routes)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = perf_counter()
        status = 500  # what the client gets when the app fails before answering

        async def send_noting_status(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, send_noting_status)
        finally:
            observe_request(self.templates.of(scope, status), scope["method"], status, perf_counter() - start)
