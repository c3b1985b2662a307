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
exec "$ROOT/.venv/bin/python" -m pytest "$@"
