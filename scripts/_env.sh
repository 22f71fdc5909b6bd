# Shared by scripts/serve.sh and scripts/test.sh: create ./.venv with Python >= 3.11 and install v3d.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PY=${PYTHON:-}
if [ -z "$PY" ]; then
  for cand in python3.11 python3.12 python3.13 python3; do
    if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
      PY=$cand; break
    fi
  done
fi
[ -n "$PY" ] || { echo "v3d needs Python >= 3.11 (set PYTHON=/path/to/python3.11)" >&2; exit 1; }
if [ ! -x .venv/bin/python ]; then
  echo "==> creating .venv with $PY"
  "$PY" -m venv .venv
fi
# The packages come from the lock file (requirements/app.lock or test.lock: exact versions with their hashes, made by
# scripts/lock.sh from pyproject.toml), so that a fresh machine installs what was tested; then v3d itself, editable.
# Re-install only when pyproject.toml or the lock changed since the last install.
stamp=.venv/.v3d-installed-$1
lock=requirements/$1.lock
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ "$lock" -nt "$stamp" ] \
   || { [ "$1" = test ] && [ requirements/evaluator.lock -nt "$stamp" ]; }; then
  echo "==> installing v3d ($1) into .venv from $lock"
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet --require-hashes -r "$lock"
  if [ "$1" = test ]; then  # SoccerNet's official evaluator, for the test that reads the cameras export with it
    .venv/bin/python -m pip install --quiet --no-deps --require-hashes -r requirements/evaluator.lock
  fi
  .venv/bin/python -m pip install --quiet --no-deps -e .
  # Compile the calibration's numba kernels once into their on-disk cache (about 15 s), so that the first
  # calibration of a server or of a test does not pay it.
  .venv/bin/python -c "from app.geometry.calibration.warmup import compile_kernels; compile_kernels()"
  touch "$stamp"
fi
