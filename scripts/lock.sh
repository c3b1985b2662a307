#!/usr/bin/env bash
# Regenerate requirements.lock from requirements.in with pip-tools.
#
# Resolves under the oldest supported Python (3.10) so every pin also
# installs on 3.10-3.13; the lock carries the hashes of all files of each
# pinned version (every cp310-cp313 wheel), so one lock serves them all.
# pip-tools lives in a throwaway venv; the machine's pip config (local
# mirrors, find-links) is ignored so the lock reflects PyPI only.
set -euo pipefail
cd "$(dirname "$0")/.."

# A pyenv shim for python3.10 may exist yet not run, so probe by running it.
PY="${LOCK_PYTHON:-python3.10}"
"$PY" -c '' 2>/dev/null || PY="$(pyenv prefix 3.10 2>/dev/null)/bin/python"
"$PY" -c 'import sys; assert sys.version_info[:2] == (3, 10), sys.version' \
  || { echo "lock.sh: need Python 3.10 (set LOCK_PYTHON=/path/to/python3.10)" >&2; exit 1; }

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export PIP_CONFIG_FILE=/dev/null
unset PIP_FIND_LINKS PIP_EXTRA_INDEX_URL PIP_INDEX_URL PIP_CONSTRAINT
"$PY" -m venv "$tmp/venv"
"$tmp/venv/bin/pip" install -q pip-tools==7.6.2
CUSTOM_COMPILE_COMMAND="scripts/lock.sh" \
  "$tmp/venv/bin/pip-compile" --quiet --generate-hashes --allow-unsafe \
    --no-strip-extras --no-emit-index-url --no-emit-find-links \
    --output-file requirements.lock requirements.in
echo "lock.sh: wrote requirements.lock"
