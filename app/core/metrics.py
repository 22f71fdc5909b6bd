"""What a team's monitoring scrapes (``GET /metrics``, Prometheus' text format), with ``prometheus-client``.

Counted as they happen, in the process serving (:data:`REQUEST_SECONDS` by the request's route template, method and
status; :data:`EDITS`; :data:`RECOMPUTATIONS`), and computed at each scrape from the database (the jobs by kind and
state, the queued ones: every node sees the same rows). Under ``v3d serve --workers N`` every worker keeps its counts
in files of ``PROMETHEUS_MULTIPROC_DIR`` (prometheus-client's multiprocess mode, which it chooses when it is first
imported with that variable set: :func:`prepare_multiprocess_dir` sets it before the workers start) and a scrape
answered by any worker adds up all of them. Each process (each node, each worker) counts its own; Prometheus sums
the nodes.
"""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path

from prometheus_client import REGISTRY, CollectorRegistry, Counter, Histogram, generate_latest, multiprocess
from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.exposition import CONTENT_TYPE_PLAIN_0_0_4

#: The variable naming prometheus-client's multiprocess folder (read by the library itself).
MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"
#: The folder this process counts in, as prometheus-client chose when imported (just above): None, in memory. Set
#: later in this process (``v3d serve --workers N`` sets it for the workers it starts) it changes nothing here.
COUNTED_IN = os.environ.get(MULTIPROC_ENV) or None
#: The exposition's content type: Prometheus' text format 0.0.4, what ``generate_latest`` writes.
CONTENT_TYPE = CONTENT_TYPE_PLAIN_0_0_4
#: The route label of a request no route matched (a 404 of an unknown path): one series, whatever the paths asked.
UNMATCHED = "unmatched"
#: The method labels counted by name: HTTP's standard methods (RFC 9110 section 9, and PATCH). Every label comes from
#: a closed set, as prometheus-client advises, so that what a client sends cannot add series: any other method a
#: client makes up is counted as :data:`OTHER_METHOD`.
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS", "CONNECT", "TRACE"})
#: The method label of a request whose method is not one of :data:`METHODS`.
OTHER_METHOD = "other"

REQUEST_SECONDS = Histogram(
    "v3d_http_request_duration_seconds",
    "Time from a request's arrival to its answer's last byte sent (s), by route template, method and status.",
    ["route", "method", "status"],
)
EDITS = Counter("v3d_edits", "Edits and decisions committed, by action and how the edit was computed (computed: "
                "before the lock; recomputed: again after meeting another write; under_lock; decided: no "
                "recomputation).", ["action", "outcome"])
RECOMPUTATIONS = Counter("v3d_system_recomputations", "Recomputations of a system's derived rows (admission, "
                         "triangulation, reprojections, optimised boxes): by edits, imports, recomputes.")


def method_label(method: str) -> str:
    """The method label of a request: ``method`` if one of :data:`METHODS`, else :data:`OTHER_METHOD`."""
    return method if method in METHODS else OTHER_METHOD


def status_label(status: int) -> str:
    """The status label of an answer: its code (100-599, all the server itself answers), else its class ``"5xx"``
    (what the ASGI server would answer for a code outside HTTP's range)."""
    return str(status) if 100 <= status <= 599 else "5xx"


def observe_request(route: str, method: str, status: int, seconds: float) -> None:
    """Count one answered request in :data:`REQUEST_SECONDS` (``route``: its template, e.g.
    ``/api/frames/{frame_id}/ball``, or :data:`UNMATCHED`; ``method`` as the client sent it, counted by
    :func:`method_label`; ``status``: the answer's code, by :func:`status_label`). Every label is from a closed set."""
    REQUEST_SECONDS.labels(route, method_label(method), status_label(status)).observe(seconds)


def count_edit(action: str, outcome: str) -> None:
    """Count one committed edit or decision (``outcome``: ``EditContext.outcome``, ``decided`` without one)."""
    EDITS.labels(action, outcome).inc()


def count_recomputation() -> None:
    """Count one recomputation of a system."""
    RECOMPUTATIONS.inc()


class _Collected:
    """A collector yielding given metric families (the scrape's figures from the database), or this process's
    default registry's (one process: no multiprocess folder)."""

    def __init__(self, families: Iterable[Metric]) -> None:
        self.families = families

    def collect(self) -> Iterable[Metric]:
        return self.families


def job_families(counts: Mapping[tuple[str, str], int], kinds: Iterable[str], states: Iterable[str]) -> list[Metric]:
    """The jobs' gauges from ``counts`` (``(kind, state) -> jobs``; every kind and state listed, 0 where none):
    ``v3d_jobs{kind,state}`` and ``v3d_jobs_queued``."""
    by = GaugeMetricFamily("v3d_jobs", "Jobs in the database by kind and state.", labels=["kind", "state"])
    kinds, states = list(kinds), list(states)
    for kind in kinds:
        for state in states:
            by.add_metric([kind, state], counts.get((kind, state), 0))
    queued = GaugeMetricFamily("v3d_jobs_queued", "Jobs waiting for a runner (every kind).",
                               value=sum(n for (_, state), n in counts.items() if state == "queued"))
    return [by, queued]


def exposition(families: Iterable[Metric] = ()) -> bytes:
    """Every metric of this process, or of every worker under the multiprocess mode, followed by ``families``
    (computed at the scrape), in Prometheus' text format."""
    registry = CollectorRegistry()
    if COUNTED_IN is not None:
        multiprocess.MultiProcessCollector(registry, path=COUNTED_IN)
    else:
        registry.register(_Collected(REGISTRY.collect()))
    registry.register(_Collected(list(families)))
    return generate_latest(registry)


def prepare_multiprocess_dir() -> Path:
    """Make the multiprocess folder ready before worker processes start: ``PROMETHEUS_MULTIPROC_DIR`` if set (its
    counts of an earlier run removed, as prometheus-client requires), else a new temporary folder, set in the
    environment the workers inherit and removed when this process exits. Returns the folder."""
    given = os.environ.get(MULTIPROC_ENV)
    if given:
        folder = Path(given)
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob("*.db"):
            old.unlink()
        return folder
    folder = Path(tempfile.mkdtemp(prefix="v3d-metrics-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    os.environ[MULTIPROC_ENV] = str(folder)
    return folder
