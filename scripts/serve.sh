#!/usr/bin/env bash
# Command 1: set up (virtual environment, packages, database migrations under ./var/), load the built-in
# demo when the database is empty, and serve on http://127.0.0.1:8000 (override with --host/--port).
set -euo pipefail
source "$(dirname "$0")/_env.sh" app
exec .venv/bin/v3d serve --demo "$@"
