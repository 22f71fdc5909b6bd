#!/usr/bin/env bash
# Command 2: run the whole test suite (installs test packages and, when root, Debian's Chromium for the
# browser tests). Extra arguments go to pytest.
set -euo pipefail
source "$(dirname "$0")/_test_env.sh"
exec .venv/bin/python -m pytest "$@"
