"""Fuzz the REST API with schemathesis (issue 7: ">= 2,000 generated requests, authenticated: 0 server errors").

The real application (``app.main.create_app``, in process over ASGI) on a fresh migrated SQLite database
seeded with the built-in demo (``app.cli.serve.load_demo_if_empty``, as ``v3d serve --demo`` does), every
operation of its ``/openapi.json``:

* **authenticated** as an admin with an API token (``app.services.accounts.users.create_user``): for each
  operation ``--examples`` cases generated from the schema (positive: valid by the schema) and as many
  negative ones (invalid by the schema: wrong types, out-of-range numbers, missing or unknown fields,
  ...). Operations with path ids draw them from the ids the database holds as often as at random, so the
  handlers behind the 404 are reached. Checks: ``not_a_server_error`` (no 5xx; an exception the app
  raises counts as one), ``status_code_conformance`` (the status is declared for the operation),
  ``content_type_conformance`` and ``response_schema_conformance`` (a declared answer matches its
  schema); a negative case must get a 4xx (``negative_data_rejection``).
* **anonymous** (no token, no cookie): every operation outside ``PUBLIC_API_PATHS`` must answer 401
  (never 5xx), ``--anonymous-examples`` cases each.

Bounded: at most ``--examples`` per operation and mode, and the run stops at ``--deadline-s`` (the
operations not reached are reported). Prints the number of requests, per-operation counts and statuses,
and each failure (operation, check, status, message) with a curl line that reproduces it; exits 1 on any
failure. Run::

    .venv/bin/python benchmarks/fuzz.py                       # 2,242 authenticated + 444 anonymous requests
    .venv/bin/python benchmarks/fuzz.py --examples 10 --only "PATCH /api/frames/{frame_id}/ball"
    createdb -h 127.0.0.1 -U postgres v3d_fuzz && .venv/bin/python benchmarks/fuzz.py \\
        --database-url postgresql+psycopg://postgres@127.0.0.1:5432/v3d_fuzz   # then dropdb

``tests/api/test_fuzz.py`` runs :func:`fuzz` with a few derandomised examples per operation.
"""
from __future__ import annotations

import argparse
import functools
import itertools
import sys
import tempfile
import time
import traceback
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Optional

import hypothesis
import schemathesis
from hypothesis import HealthCheck, Phase
from hypothesis import strategies as st
from schemathesis import GenerationMode
from schemathesis.checks import not_a_server_error
from schemathesis.core.failures import FailureGroup
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    negative_data_rejection,
    response_schema_conformance,
    status_code_conformance,
)

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from app.api.authentication import PUBLIC_API_PATHS

#: Checks of every authenticated answer (schemathesis' own check functions).
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]
#: A negative case (invalid by the schema) must be refused with a 4xx.
NEGATIVE_CHECKS = [*CHECKS, negative_data_rejection]
#: Operations whose valid cases hash a password with argon2 (~0.5 s each here): fewer examples.
SLOW_OPERATIONS = {"POST /api/auth/login": 0.2, "POST /api/users": 0.2}


@dataclass
class Failure:
    """One failed check: the operation, the check's name, the answer's status, the message, and a
    curl line that sends the same request."""

    operation: str
    check: str
    status: Optional[int]
    message: str
    curl: str


@dataclass
class FuzzReport:
    """What a run sent and found. ``requests`` per operation label (``"PATCH /api/frames/{frame_id}/ball"``),
    ``statuses`` per operation (status -> count), ``failures`` (one per distinct operation, check, status and
    message), ``skipped`` the operations the deadline left out."""

    requests: Counter = field(default_factory=Counter)
    statuses: dict[str, Counter] = field(default_factory=dict)
    failures: list[Failure] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    seconds: float = 0.0
    op_seconds: Counter = field(default_factory=Counter)

    @property
    def total(self) -> int:
        """Requests sent."""
        return sum(self.requests.values())

    @property
    def server_errors(self) -> int:
        """Answers with a 5xx status (an exception the app raised counts as a 500)."""
        return sum(n for counts in self.statuses.values() for code, n in counts.items() if code >= 500)

    def add_failure(self, failure: Failure) -> None:
        """Keep ``failure`` unless an equal one (operation, check, status, message) is already kept."""
        key = (failure.operation, failure.check, failure.status, failure.message)
        if all((f.operation, f.check, f.status, f.message) != key for f in self.failures):
            self.failures.append(failure)


def load_schema(app: Any) -> Any:
    """The schemathesis schema of ``app``'s ``/openapi.json`` (in-process ASGI transport)."""
    return schemathesis.openapi.from_asgi("/openapi.json", app)


def operations(schema: Any) -> list[Any]:
    """Every operation of the schema (schemathesis ``APIOperation``), in the schema's order."""
    return [result.ok() for result in schema.get_all_operations()]


def is_public(operation: Any) -> bool:
    """True for the operations answered without a principal (``PUBLIC_API_PATHS``)."""
    return operation.path in PUBLIC_API_PATHS


def case_strategy(operation: Any, mode: GenerationMode, path_ids: dict[str, list[Any]]) -> st.SearchStrategy:
    """Cases of ``operation`` in ``mode``; where the path names a parameter of ``path_ids`` (e.g.
    ``frame_id``), half of them take one of its known values (existing rows) and half are generated; with several
    such parameters, the known values are also combined (``/api/users/{name}/tokens/{token_id}`` of a real token)."""
    names = [p.name for p in operation.path_parameters] if operation.path_parameters else []
    free = operation.as_strategy(generation_mode=mode)
    known = [name for name in names if path_ids.get(name)]
    if not known or mode is GenerationMode.NEGATIVE:
        return free
    fixed = [
        operation.as_strategy(generation_mode=mode, path_parameters={name: value})
        for name in known for value in path_ids[name]
    ]
    if len(known) > 1:  # every known value at once (a user's name and one of its token ids): the handler's success
        fixed += [operation.as_strategy(generation_mode=mode, path_parameters=dict(zip(known, values, strict=False)))
                  for values in itertools.product(*(path_ids[name] for name in known))]
    return st.one_of(free, st.one_of(fixed))


def _curl(case: Any, headers: dict[str, str]) -> str:
    try:
        return case.as_curl_command(headers=headers, base_url="http://127.0.0.1:8000")
    except Exception as exc:  # any exception: a reproduction line is best effort
        return f"(no curl line: {exc})"


def _hypothesis_run(strategy: Any, send: Callable[[Any], None], n: int, seed: Optional[int]) -> Callable[[], None]:
    """A Hypothesis test sending ``n`` cases of ``strategy`` through ``send`` (a fixed seed when given)."""
    @hypothesis.settings(max_examples=n, deadline=None, database=None, derandomize=seed is None,
                         suppress_health_check=list(HealthCheck), phases=[Phase.explicit, Phase.generate],
                         print_blob=False)
    @hypothesis.given(case=strategy)
    def run(case: Any) -> None:
        send(case)

    return hypothesis.seed(seed)(run) if seed is not None else run


def _send(case: Any, headers: dict[str, str], report: FuzzReport, label: str,
          checks: list[Callable], expect_status: Optional[int] = None,
          etag_of: Optional[Callable[[Any], Optional[str]]] = None) -> None:
    """Send ``case`` (with ``If-Match: etag_of(case)`` when that gives one), count it, and record every
    failed check (an exception raised by the app is a 500)."""
    etag = etag_of(case) if etag_of is not None else None
    if etag is not None:
        headers = {**headers, "If-Match": etag}
    report.requests[label] += 1
    counts = report.statuses.setdefault(label, Counter())
    try:
        response = case.call(headers=headers)
    except Exception as exc:  # any exception: the app raised: a server error
        counts[500] += 1
        tail = "".join(traceback.format_exception_only(type(exc), exc)).strip().splitlines()[0]
        report.add_failure(Failure(label, "not_a_server_error (exception)", 500, tail[:300], _curl(case, headers)))
        return
    counts[response.status_code] += 1
    if expect_status is None and response.status_code == 401 and not label.startswith("POST /api/auth/login"):
        # authenticated: a 401 means the pass lost its principal (its own token revoked, its user disabled), and
        # every later case would stop at the 401 instead of reaching its handler (path ids: :func:`prepare`)
        report.add_failure(Failure(label, "the fuzzing principal was lost (401)", 401, response.text[:300],
                                   _curl(case, headers)))
    if expect_status is not None and response.status_code != expect_status:
        report.add_failure(Failure(label, f"status {expect_status}", response.status_code,
                                   response.text[:300], _curl(case, headers)))
    try:
        case.validate_response(response, checks=checks, headers=headers)
    except (AssertionError, FailureGroup) as exc:  # one failed check, or a group of them
        for failure in getattr(exc, "exceptions", [exc]):
            title = getattr(failure, "title", type(failure).__name__)
            message = (getattr(failure, "message", None) or str(failure)).strip().splitlines()
            report.add_failure(Failure(label, str(title), response.status_code,
                                       (message[0] if message else "")[:300], _curl(case, headers)))


def admin_headers(token: str) -> dict[str, str]:
    """The authenticated pass's headers: the admin's API token. Its conditional writes name the current
    version of their resource (:func:`current_etags`), as a script must: a token's write without a real
    ETag gets 428 (``tests/api/routes/test_audit_etags.py``)."""
    return {"Authorization": f"Bearer {token}"}


#: Conditional writes (``If-Match``) by the path parameter that names their resource, and the GET that
#: answers that resource's current ETag.
ETAG_SOURCES = {"frame_id": "/api/frames/{}", "system_id": "/api/systems/{}"}


def current_etags(app: Any, headers: dict[str, str]) -> Callable[[Any], Optional[str]]:
    """For a case, the current ``ETag`` of the frame or system its path names (read with a GET of
    :data:`ETAG_SOURCES` just before the case is sent, with ``headers``), so that fuzzed writes reach their
    handlers instead of the 428 or 412; None for a read, a path without such an id, or an id that answers
    no ETag (a generated one that does not exist: the write then gets its 428)."""
    from starlette.testclient import TestClient

    client = TestClient(app, headers=headers)

    def etag(case: Any) -> Optional[str]:
        if case.method.upper() == "GET":
            return None
        for name, path in ETAG_SOURCES.items():
            value = (case.path_parameters or {}).get(name)
            if value is not None:
                try:
                    return client.get(path.format(value)).headers.get("etag")
                except Exception:  # any exception: an id the GET cannot take is the case's own business
                    return None
        return None

    return etag


def fuzz(schema: Any, headers: dict[str, str], *, examples: int, path_ids: dict[str, list[Any]] | None = None,
         modes: Iterable[GenerationMode] = (GenerationMode.POSITIVE, GenerationMode.NEGATIVE),
         anonymous: bool = False, only: Optional[set[str]] = None, seed: Optional[int] = None,
         deadline: Optional[float] = None, report: Optional[FuzzReport] = None,
         etag_of: Optional[Callable[[Any], Optional[str]]] = None) -> FuzzReport:
    """Send up to ``examples`` generated cases per operation of ``schema`` and per mode.

    Args:
        headers: sent with every request (``Authorization: Bearer <token>``; empty for ``anonymous``).
        path_ids: known values of path parameters (``{"frame_id": [1, 2]}``), see :func:`case_strategy`.
        anonymous: send no credentials; every non-public operation must answer 401, public ones are skipped.
        only: operation labels to fuzz (all when None).
        seed: Hypothesis seed; None: derandomised (the same cases every run).
        deadline: ``time.monotonic()`` after which no operation is started (they go to ``skipped``).
        etag_of: the ``If-Match`` of a case (:func:`current_etags`), or None for none.

    Returns:
        The report (``report`` extended when given).
    """
    report = report or FuzzReport()
    start = time.monotonic()
    for operation in operations(schema):
        label = operation.label
        if (only and label not in only) or (anonymous and is_public(operation)):
            continue
        if deadline is not None and time.monotonic() > deadline:
            report.skipped.append(label)
            continue
        n = max(1, round(examples * SLOW_OPERATIONS.get(label, 1.0)))
        op_start = time.monotonic()
        for mode in modes:
            checks = NEGATIVE_CHECKS if mode is GenerationMode.NEGATIVE else CHECKS
            send = functools.partial(_send, headers=headers, report=report, label=label,
                                     checks=[not_a_server_error] if anonymous else checks,
                                     expect_status=401 if anonymous else None,
                                     etag_of=None if anonymous else etag_of)
            run = _hypothesis_run(case_strategy(operation, mode, path_ids or {}), send, n, seed)
            try:
                run()
            except hypothesis.errors.Unsatisfiable:
                pass  # nothing in the operation can be made invalid (e.g. no parameters, no body)
        report.op_seconds[label] += time.monotonic() - op_start
    report.seconds += time.monotonic() - start
    return report


#: A media type no operation declares (issue 27): a body of it must be refused with 415 before it is read, never
#: fail, whatever the route.
UNDECLARED_MEDIA_TYPE = "application/xml"


def fuzz_media_types(schema: Any, headers: dict[str, str], *, examples: int,
                     path_ids: dict[str, list[Any]] | None = None, report: Optional[FuzzReport] = None,
                     etag_of: Optional[Callable[[Any], Optional[str]]] = None) -> FuzzReport:
    """Bodies of every media type an operation declares, and of :data:`UNDECLARED_MEDIA_TYPE`, to every operation
    that takes a body (``app.api.bodies``: each route takes only its own types). Per operation and declared type
    ``examples`` positive cases sent as that type (the checks of :data:`CHECKS`; labels
    ``"POST /api/imports [multipart/form-data]"``); then as many with the case's body sent as the undeclared type,
    which must answer 415 (a declared status) and no server error."""
    report = report or FuzzReport()
    start = time.monotonic()
    for operation in operations(schema):
        declared = list(operation.get_request_payload_content_types())
        if not declared:
            continue
        for media in [*declared, UNDECLARED_MEDIA_TYPE]:
            _fuzz_one_media_type(operation, media, declared, headers, examples, path_ids or {}, report, etag_of)
    report.seconds += time.monotonic() - start
    return report


def _fuzz_one_media_type(operation: Any, media: str, declared: list[str], headers: dict[str, str], examples: int,
                         path_ids: dict[str, list[Any]], report: FuzzReport,
                         etag_of: Optional[Callable[[Any], Optional[str]]]) -> None:
    label = f"{operation.label} [{media}]"
    generated_as = media if media in declared else declared[0]
    n = max(1, round(examples * SLOW_OPERATIONS.get(operation.label, 1.0)))

    @hypothesis.settings(max_examples=n, deadline=None, database=None, derandomize=True,
                         suppress_health_check=list(HealthCheck), phases=[Phase.explicit, Phase.generate],
                         print_blob=False)
    @hypothesis.given(case=case_strategy(operation, GenerationMode.POSITIVE, path_ids))
    def run(case: Any) -> None:
        case.media_type = generated_as  # the body serialised as this type, the header naming it
        if media == generated_as:
            _send(case, headers, report, label, CHECKS, None, etag_of)
            return
        case.media_type = media
        case.body = repr(case.body).encode()[:4096]  # some bytes, said to be of a type nobody takes
        _send(case, headers, report, label, [not_a_server_error, status_code_conformance], 415, etag_of)

    run()


# ----- the benchmark: a fresh demo database, an admin token, both runs --------------------------------------
def prepare(workdir: Path, database_url: Optional[str] = None) -> tuple[Any, str, dict[str, list[Any]]]:
    """Migrate the database (default: a SQLite file in ``workdir``; else ``database_url``, an empty
    database), import the demo into it and make an admin with an API token. ``workdir`` is the data root.
    Returns the settings, the token and known path ids (a few frames, systems, games; the name and token ids of
    another user, ``fuzz-target``, so that the pass never revokes or disables its own principal)."""
    import sqlalchemy as sa

    from app.cli.serve import load_demo_if_empty
    from app.core.config import Settings
    from app.db.models import Frame, Game, System
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.accounts.users import create_user, issue_token

    url = database_url or f"sqlite:///{workdir / 'fuzz.sqlite3'}"
    upgrade_database(url)
    # schemathesis' in-process ASGI transport names the host ``testserver``: allowed here by name (app.api.hosts)
    settings = Settings(database_url=url, calibration_workers=1, data_root=workdir, allowed_hosts=["testserver"])
    print(load_demo_if_empty(settings), flush=True)
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            _, token = create_user(session, "fuzz-admin", "admin", "fuzz-admin password")
            # the user routes' known name is another user's, with tokens of its own: the pass may change its role,
            # disable it and revoke its tokens, never its own principal
            create_user(session, "fuzz-target", "annotator", "fuzz-target password")
            target_tokens = [issue_token(session, "fuzz-target", label=f"t{i}").id for i in range(3)]
            ids = {
                "frame_id": session.scalars(sa.select(Frame.id).order_by(Frame.id).limit(4)).all(),
                "system_id": session.scalars(sa.select(System.id).order_by(System.id).limit(3)).all(),
                "game_id": session.scalars(sa.select(Game.id).order_by(Game.id).limit(2)).all(),
                "name": ["fuzz-target"],
                "token_id": target_tokens,
            }
    finally:
        engine.dispose()
    return settings, token, ids


def print_report(title: str, report: FuzzReport) -> None:
    """Requests, statuses per operation, failures with their curl lines."""
    print(f"\n== {title}: {report.total} requests in {report.seconds:.1f} s, {report.server_errors} server errors, "
          f"{len(report.failures)} distinct failures")
    for label, n in report.requests.items():
        statuses = " ".join(f"{code}x{k}" for code, k in sorted(report.statuses[label].items()))
        print(f"  {n:5d}  {label:52s} {report.op_seconds[label]:6.1f} s  {statuses}")
    for label in report.skipped:
        print(f"  skipped (deadline): {label}")
    for f in report.failures:
        print(f"\nFAIL {f.operation}: {f.check} (status {f.status}): {f.message}\n  {f.curl}")


def main(argv: Optional[list[str]] = None) -> int:
    """Command line: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=50, help="cases per operation and mode (authenticated)")
    parser.add_argument("--anonymous-examples", type=int, default=10, help="cases per operation, anonymous")
    parser.add_argument("--seed", type=int, default=None, help="Hypothesis seed (default: derandomised)")
    parser.add_argument("--deadline-s", type=float, default=1200.0, help="start no operation after this")
    parser.add_argument("--database-url", help="an empty database to fuzz on (default: a fresh SQLite file), "
                                               "e.g. postgresql+psycopg://postgres@127.0.0.1:5432/v3d_fuzz")
    parser.add_argument("--only", action="append", help='an operation label, e.g. "GET /api/frames" (repeatable)')
    args = parser.parse_args(argv)
    from app.main import create_app

    with tempfile.TemporaryDirectory(prefix="v3d-fuzz-") as tmp:
        settings, token, path_ids = prepare(Path(tmp), args.database_url)
        app = create_app(settings)
        schema = load_schema(app)
        deadline = time.monotonic() + args.deadline_s
        only = set(args.only) if args.only else None
        headers = admin_headers(token)
        authed = fuzz(schema, headers, examples=args.examples, path_ids=path_ids,
                      only=only, seed=args.seed, deadline=deadline, etag_of=current_etags(app, headers))
        print_report("authenticated (admin token)", authed)
        anon = fuzz(schema, {}, examples=args.anonymous_examples, path_ids=path_ids, anonymous=True, only=only,
                    seed=args.seed, deadline=deadline)
        print_report("anonymous (every non-public operation must answer 401)", anon)
    failed = len(authed.failures) + len(anon.failures)
    print(f"\nTOTAL: {authed.total + anon.total} requests ({authed.total} authenticated, {anon.total} anonymous), "
          f"{authed.server_errors + anon.server_errors} server errors, {failed} distinct failures")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
