#!/usr/bin/env bash
# Re-pin what a fresh machine installs: requirements/app.lock (the service) and requirements/test.lock (the service
# and the test packages), every package at one version with its hashes, for every platform and Python >= 3.11,
# resolved from pyproject.toml by uv. Run after changing a dependency in pyproject.toml; then run the tests
# (scripts/_env.sh re-installs from the new lock) and commit pyproject.toml with the locks.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/python ] || { echo "run scripts/test.sh once first (it makes .venv)" >&2; exit 1; }
.venv/bin/python -m uv --version >/dev/null 2>&1 || .venv/bin/python -m pip install --quiet uv
for kind in app test; do
  extra=(); [ "$kind" = test ] && extra=(--extra test)
  .venv/bin/python -m uv pip compile pyproject.toml "${extra[@]}" --universal --python-version 3.11 \
    --generate-hashes --no-header --quiet -o "requirements/$kind.lock"
  echo "requirements/$kind.lock: $(grep -c '^[A-Za-z0-9]' "requirements/$kind.lock") packages"
done
