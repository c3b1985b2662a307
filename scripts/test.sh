#!/usr/bin/env bash
# Run the test suite in the project venv: scripts/test.sh [pytest args...]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
# DDS discovery stays on this host (no multicast on real interfaces).
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
# The pip wheels don't set it; ament_index lookups need the venv prefix.
export AMENT_PREFIX_PATH="$ROOT/.venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
# One worker process per core, at most 4 (pytest-xdist; each worker's graphs take
# domain ids from a band of their own, tests/shared.py), a file's tests on one
# worker (they share module fixtures), files in tests/conftest.py's order (long
# ones first). `-n 0` runs them in this process (with -s).
exec "$ROOT/.venv/bin/python" -m pytest -n auto --maxprocesses 4 --dist loadfile \
  --no-loadscope-reorder "$@"
