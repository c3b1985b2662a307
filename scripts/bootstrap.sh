#!/usr/bin/env bash
# Create/refresh <repo>/.venv from requirements.lock, then install this
# project into it (editable). Idempotent and cheap when nothing changed:
# stamps in .venv record what was installed last.
#   PYTHON=/path/to/python3.X scripts/bootstrap.sh   # pick an interpreter
#   rm -rf .venv && scripts/bootstrap.sh             # clean rebuild
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
VENV="$ROOT/.venv"
LOCK="$ROOT/requirements.lock"
PY="${PYTHON:-python3}"
say() { echo "bootstrap: $*"; }
die() { echo "bootstrap: ERROR: $*" >&2; exit 1; }

# The ROS 2 wheels exist for CPython 3.10-3.13 only.
check_python() {
  command -v "$1" >/dev/null || die "$1 not found; need Python 3.10-3.13 (set PYTHON=...)"
  "$1" -c 'import sys; sys.exit(0 if (3, 10) <= sys.version_info[:2] <= (3, 13) else 1)' 2>/dev/null \
    || die "$1 is $("$1" -V 2>&1); need Python 3.10-3.13 (set PYTHON=...)"
}

# 0. Headless rendering of MuJoCo bodies (docs/mujoco.md) needs EGL and Mesa's
#    drivers: Debian's libegl1, libegl-mesa0 and libgl1-mesa-dri. Installed
#    when missing and we may (root, or sudo without a password); otherwise
#    the command to run is printed and the MuJoCo tests skip, saying why.
egl_present() {
  { ldconfig -p 2>/dev/null || true; } | grep -q 'libEGL_mesa.so.0' \
    && { ldconfig -p 2>/dev/null || true; } | grep -q 'libEGL.so.1' \
    && ls /usr/lib/*/dri/*_dri.so >/dev/null 2>&1
}
EGL_PACKAGES="libegl1 libegl-mesa0 libgl1-mesa-dri"
if ! egl_present; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    say "installing EGL for MuJoCo rendering: $EGL_PACKAGES"
    apt-get install -y $EGL_PACKAGES >/dev/null 2>&1 \
      || { apt-get update >/dev/null 2>&1 && apt-get install -y $EGL_PACKAGES >/dev/null 2>&1; } \
      || say "WARNING: apt-get install $EGL_PACKAGES failed; MuJoCo bodies cannot render"
  elif command -v apt-get >/dev/null && command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
    say "installing EGL for MuJoCo rendering: $EGL_PACKAGES"
    sudo -n apt-get install -y $EGL_PACKAGES >/dev/null 2>&1 \
      || say "WARNING: sudo apt-get install $EGL_PACKAGES failed; MuJoCo bodies cannot render"
  else
    say "WARNING: no EGL found; MuJoCo bodies cannot render (their tests skip). Install it with:"
    say "  sudo apt-get install -y $EGL_PACKAGES"
  fi
fi

mkdir -p "$VENV"
# Serialise concurrent runs (e.g. scripts/test.sh and scripts/main.sh).
if command -v flock >/dev/null; then exec 9>"$VENV/.bootstrap.lock"; flock 9; fi

if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c '' 2>/dev/null; then
  check_python "$PY"
  say "creating .venv with $("$PY" -V 2>&1)"
  rm -f "$VENV/.lock.sha256" "$VENV/.project.sha256"  # force full install
  "$PY" -m venv "$VENV"
fi
check_python "$VENV/bin/python"
PIP=("$VENV/bin/python" -m pip --disable-pip-version-check -q)
# pip, minus one warning per package from machines whose pip config lists
# local file:// mirrors that lack most packages.
pip() { "${PIP[@]}" "$@" 2>&1 | { grep -v "^WARNING: Location 'file:" || true; }; }

# 1. Third-party packages, exactly as locked (hash-checked).
lock_sum="$(sha256sum "$LOCK" | cut -d' ' -f1)"
if [ "$(cat "$VENV/.lock.sha256" 2>/dev/null)" = "$lock_sum" ]; then
  say "requirements.lock unchanged, skipping install"
else
  say "installing requirements.lock (hash-checked)"
  # empy (needed by ros-rosidl-adapter) is published only as an sdist. Build
  # it against the locked setuptools/wheel (--no-build-isolation) instead of
  # letting pip fetch unpinned build tools; so install those two first, with
  # their hashes taken from the lock itself.
  tools="$(mktemp)"; trap 'rm -f "$tools"' EXIT
  awk '/^(setuptools|wheel)==/{p=1} p{print; if ($0 !~ /\\$/) p=0}' "$LOCK" >"$tools"
  pip install --require-hashes --no-deps -r "$tools"
  pip install --require-hashes --no-build-isolation -r "$LOCK"
  echo "$lock_sum" >"$VENV/.lock.sha256"
  rm -f "$VENV/.project.sha256"  # reinstall the project on top of new deps
fi

# 2. This project, editable; redone when its packaging changes (entry points).
proj_sum="$(cat setup.py setup.cfg | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$VENV/.project.sha256" 2>/dev/null)" = "$proj_sum" ]; then
  say "sensorispace_ros unchanged, skipping install"
else
  say "installing sensorispace_ros (editable)"
  # --use-pep517: without a pyproject.toml, pip would fall back to the
  # legacy `setup.py develop`, which setuptools >= 80 rejects ("no such option
  # 'script_dir'") and which would put scripts in .venv/lib/sensorispace_ros.
  # The PEP 660 path ignores setup.cfg's script_dir: scripts land in .venv/bin.
  pip install --no-deps --no-build-isolation --use-pep517 -e "$ROOT"
  [ -x "$VENV/bin/sensorispace" ] || die ".venv/bin/sensorispace missing after install"
  echo "$proj_sum" >"$VENV/.project.sha256"
fi

# 3. PEP 660 editable wheels carry no data_files, so mirror setup.py's
#    data_files as symlinks into the source tree (edits show up live) and
#    the ament index marker, so get_package_share_directory() works.
share="$VENV/share/sensorispace_ros"
mkdir -p "$share" "$VENV/share/ament_index/resource_index/packages"
for f in package.xml config msg_schemas launch; do ln -sfn "$ROOT/$f" "$share/$f"; done
ln -sfn "$ROOT/resource/sensorispace_ros" "$VENV/share/ament_index/resource_index/packages/sensorispace_ros"
say "ready: $("$VENV/bin/python" -V 2>&1) in .venv"
