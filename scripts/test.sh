#!/usr/bin/env bash
# Command 2: the test suite, in one of three tiers (docs/testing.md). Extra arguments go to pytest.
#   bash scripts/test.sh          CI's suite (.ci/run runs it): every behaviour at a size that fits, on SQLite; then
#                                 the tests whose behaviour depends on the database engine again on PostgreSQL
#                                 (V3D_CI_POSTGRES_URL, the local server by default; said and skipped when it is down)
#   bash scripts/test.sh --quick  geometry, services and API on SQLite, no browser, no processes of their own, no
#                                 test that reads ../shared's data sets, no database copy per test (served), no fuzzing:
#                                 the edit-run loop
#   bash scripts/test.sh --slow   the full-size load, concurrency, fault, fuzz, upgrade and two-node runs
# Each pass runs on V3D_TEST_WORKERS pytest-xdist workers (2: both cores of the machine CI runs on). Installs the
# test packages and, when root, Debian's Chromium for the browser tests.
set -euo pipefail
tier=ci
case "${1:-}" in
  --quick) tier=quick; shift ;;
  --slow) tier=slow; shift ;;
esac
source "$(dirname "$0")/_test_env.sh"
PG=${V3D_CI_POSTGRES_URL:-postgresql+psycopg://postgres@127.0.0.1:5432/test}
pytest=(.venv/bin/python -m pytest -n "${V3D_TEST_WORKERS:-2}" --dist loadgroup)

# Exit status 5 is pytest's "no test selected": a pass whose marks select none of the tests asked for (a path of
# geometry tests has no PostgreSQL tests) is no failure.
run_pass() {
  local rc=0
  "$@" || rc=$?
  [ "$rc" = 5 ] && return 0
  return "$rc"
}

postgres_reachable() {
  .venv/bin/python - "$PG" <<'PY'
import sys, sqlalchemy as sa
try:
    sa.create_engine(sys.argv[1]).connect().close()
except sa.exc.OperationalError as exc:
    print(f"==> PostgreSQL not reachable at {sys.argv[1]} ({str(exc.orig).strip().splitlines()[0]}): "
          "the PostgreSQL pass is skipped", file=sys.stderr)
    sys.exit(1)
PY
}

case "$tier" in
  quick)
    exec "${pytest[@]}" -m "not (browser or processes or slow or postgres or shared or served or fuzz)" tests/geometry tests/services \
      tests/api app "$@" ;;
  slow)
    exec "${pytest[@]}" -m slow "$@" ;;
esac
status=0
echo "==> SQLite pass: every test but the slow tier's and those of PostgreSQL itself"
run_pass "${pytest[@]}" -m "not (slow or postgres)" "$@" || status=$?
if postgres_reachable; then
  echo "==> PostgreSQL pass ($PG): the engine's tests and those of PostgreSQL itself"
  V3D_TEST_DATABASE_URL="$PG" run_pass "${pytest[@]}" -m "(engine or postgres) and not slow" "$@" || status=$?
fi
exit "$status"
