#!/usr/bin/env bash
# Idempotent set-up of a Python venv holding ROS 2 (from the PyPI wheels), the ext_sense_msgs
# interface package built into it, and every Python package of src/ installed editable.
#
# Usage: scripts/setup.sh [kilted|jazzy]      (default kilted -> .venv, jazzy -> .venv-jazzy)
#
# Each of the three steps keeps a stamp (a hash of its inputs) in the venv and is skipped when
# nothing it depends on changed, so a second run takes well under a second.
# The Dockerfile does not run this script: on a real ROS install colcon builds the workspace and
# only requirements/python.txt is pip-installed.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DISTRO=${1:-kilted}
case "$DISTRO" in
  kilted) VENV=${EXT_SENSE_VENV:-$ROOT/.venv} ;;
  jazzy) VENV=${EXT_SENSE_VENV:-$ROOT/.venv-jazzy} ;;
  *) echo "setup.sh: unknown distribution '$DISTRO' (expected kilted or jazzy)" >&2; exit 2 ;;
esac
PY=${PYTHON:-python3}
PIP_FLAGS=(--disable-pip-version-check --quiet --no-warn-script-location)

stamp_of() { cat "$@" 2>/dev/null | sha256sum | cut -c1-16; }
fresh() { [ -f "$VENV/.stamp-$1" ] && [ "$(cat "$VENV/.stamp-$1")" = "$2" ]; }
mark() { echo "$2" > "$VENV/.stamp-$1"; }

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup: creating $VENV" >&2
  "$PY" -m venv "$VENV"
fi
VPY="$VENV/bin/python"

# 1. Python and ROS wheels.
REQS=("$ROOT/requirements/ros-$DISTRO.txt" "$ROOT/requirements/python.txt" "$ROOT/requirements/dev.txt")
s=$(stamp_of "${REQS[@]}" "$0")
if ! fresh deps "$s"; then
  echo "setup: installing wheels for ROS 2 $DISTRO (a minute on first run)" >&2
  "$VPY" -m pip install "${PIP_FLAGS[@]}" --upgrade pip setuptools wheel
  "$VPY" -m pip install "${PIP_FLAGS[@]}" -r "$ROOT/requirements/ros-$DISTRO.txt" \
    -r "$ROOT/requirements/python.txt" -r "$ROOT/requirements/dev.txt"
  # Fix 1: the wheels were built in manylinux; their exported CMake files name include dirs
  # under /opt/python/cp311-cp311/. Point them at this interpreter's.
  PYINC=$("$VPY" -c "import sysconfig; print(sysconfig.get_paths()['include'])")
  NPINC=$("$VPY" -c "import numpy; print(numpy.get_include())")
  { grep -l /opt/python/cp311-cp311 "$VENV"/share/*/cmake/*.cmake 2>/dev/null || true; } \
    | xargs -r sed -i \
      -e "s#/opt/python/cp311-cp311/include/python3.11#$PYINC#g" \
      -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$NPINC#g"
  mark deps "$s"
  rm -f "$VENV/.stamp-msgs"
fi

# 2. The interface package, built with cmake into the venv prefix.
MSGS="$ROOT/src/ext_sense_msgs"
s=$(stamp_of "$MSGS"/CMakeLists.txt "$MSGS"/package.xml "$MSGS"/msg/*.msg "$0")
if ! fresh msgs "$s"; then
  echo "setup: building ext_sense_msgs" >&2
  BUILD="$ROOT/build/$DISTRO/ext_sense_msgs"
  rm -rf "$BUILD"; mkdir -p "$(dirname "$BUILD")"
  # Fix 2: without AMENT_PREFIX_PATH rosidl finds no typesupport ("No 'rosidl_typesupport_c'").
  # Fix 3: Python3 must be this venv's interpreter, not the system's.
  AMENT_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH" cmake -S "$MSGS" -B "$BUILD" \
    -DBUILD_TESTING=OFF -DCMAKE_PREFIX_PATH="$VENV" -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DPython3_EXECUTABLE="$VPY" -DPYTHON_EXECUTABLE="$VPY" >"$BUILD.log" 2>&1 \
    || { cat "$BUILD.log" >&2; exit 1; }
  AMENT_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH" cmake --build "$BUILD" -j2 >>"$BUILD.log" 2>&1 \
    && cmake --install "$BUILD" >>"$BUILD.log" 2>&1 || { tail -50 "$BUILD.log" >&2; exit 1; }
  "$VPY" -c "from ext_sense_msgs.msg import BioTacFrame, TaxelEventBatch, ContactWindow, ContactEstimate, ContactGroundTruth" \
    || { echo "setup: ext_sense_msgs built but does not import" >&2; exit 1; }
  mark msgs "$s"
fi

# 3. Every Python package of src/, editable (code changes need no reinstall; only a changed
#    setup.py or a new package triggers this step).
PKGS=()
for d in "$ROOT"/src/*/; do [ -f "$d/setup.py" ] && PKGS+=("$d"); done
s=$(stamp_of "${PKGS[@]/%//setup.py}" "$0")
if [ ${#PKGS[@]} -gt 0 ] && ! fresh editable "$s"; then
  echo "setup: installing ${#PKGS[@]} packages of src/ editable" >&2
  args=(); for d in "${PKGS[@]}"; do args+=(-e "$d"); done
  mkdir -p "$ROOT/build"
  "$VPY" -m pip install "${PIP_FLAGS[@]}" --no-deps --no-build-isolation "${args[@]}" \
    >"$ROOT/build/editable-$DISTRO.log" 2>&1 || { cat "$ROOT/build/editable-$DISTRO.log" >&2; exit 1; }
  mark editable "$s"
fi
