#!/usr/bin/env bash
# Idempotent set-up of a Python venv holding ROS 2 (from the PyPI wheels), the ext_sense_msgs
# interface package built into it, every Python package of src/ installed editable, and (kilted,
# when a CPU-only wheel is reachable) torch for training the GRU model.
#
# Usage: scripts/setup.sh [kilted|jazzy]      (default kilted -> .venv, jazzy -> .venv-jazzy)
#
# Each step keeps a stamp (a hash of its inputs) in the venv and is skipped when
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

# 2. Every Python package of src/, editable (code changes need no reinstall; only a changed
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

# 2b. colcon, to build ros2_ws as a ROS user does (`make colcon`, test_colcon_workspace.py), in a
#     directory of its own: colcon-core pins setuptools<80 and brings pytest plugins, which must
#     not replace the venv's setuptools nor join its test runs (requirements/colcon.txt). The
#     `colcon` command in $VENV/bin runs it with this venv's Python (so what colcon installs runs
#     on the venv's ROS), that directory first on PYTHONPATH.
COLCON_REQ="$ROOT/requirements/colcon.txt"
s=$(stamp_of "$COLCON_REQ" "$0")
if ! fresh colcon "$s"; then
  echo "setup: installing colcon into $VENV/colcon" >&2
  rm -rf "$VENV/colcon"
  "$VPY" -m pip install "${PIP_FLAGS[@]}" --target "$VENV/colcon" -r "$COLCON_REQ"
  cat > "$VENV/bin/colcon" <<EOF
#!/bin/sh
# colcon from $VENV/colcon (scripts/setup.sh, requirements/colcon.txt)
PYTHONPATH="$VENV/colcon\${PYTHONPATH:+:\$PYTHONPATH}" exec "$VENV/colcon/bin/colcon" "\$@"
EOF
  chmod +x "$VENV/bin/colcon"
  mark colcon "$s"
fi

# 3. Optional training extra (torch, for the GRU model), only as a CPU-only build: the explicit
#    local version (torch==X+cpu) cannot pull the gigabytes of CUDA that plain `torch` does.
#    Found through pip's own configuration (here find-links /opt/wheels; elsewhere e.g.
#    PIP_EXTRA_INDEX_URL=https://download.pytorch.org/whl/cpu). Default on for kilted, off for
#    the jazzy venv (node tests only); EXT_SENSE_TRAIN=0 or 1 overrides.
#    When no such wheel exists the GRU tests skip; `rm $VENV/.stamp-train` to try again.
#    It installs in the background while step 4 compiles (mostly unpacking and byte-compiling
#    on one core, beside builds that leave a core idle at times); no other pip runs meanwhile.
install_train_extra() {
  TRAIN_REQ="$ROOT/requirements/train.txt"
  s=$(stamp_of "$TRAIN_REQ" "$0")
  TRAIN_DEFAULT=$([ "$DISTRO" = kilted ] && echo 1 || echo 0)
  if [ "${EXT_SENSE_TRAIN:-$TRAIN_DEFAULT}" != 0 ] && [ -f "$TRAIN_REQ" ] && ! fresh train "$s"; then
    TORCH=$(sed -n 's/^\(torch==[0-9][0-9.]*\).*/\1/p' "$TRAIN_REQ" | head -1)
    mkdir -p "$ROOT/build"
    if [ -n "$TORCH" ] && "$VPY" -c "import torch, sys; sys.exit(torch.__version__ != '${TORCH#torch==}+cpu')" 2>/dev/null; then
      :  # already installed
    elif [ -n "$TORCH" ] && "$VPY" -m pip install "${PIP_FLAGS[@]}" --only-binary=:all: \
        "$TORCH+cpu" >"$ROOT/build/train-$DISTRO.log" 2>&1; then
      echo "setup: installed $TORCH+cpu (optional training extra, GRU model)" >&2
    else
      echo "setup: no CPU-only wheel of ${TORCH:-torch} (+cpu) found, training extra skipped: the GRU tests will skip (details: build/train-$DISTRO.log)" >&2
    fi
    mark train "$s"
  fi
}
install_train_extra &
TRAIN_PID=$!
trap 'wait "$TRAIN_PID" 2>/dev/null || true' EXIT  # a failed build below leaves no pip behind

# 4. The interface packages, built with cmake into the venv prefix: ours (ext_sense_msgs), and
#    the parts of control_msgs and franka_msgs we use, which are not on PyPI (interfaces/,
#    definitions byte-identical to upstream; on a ROS install the real packages are used).
#    A file that differs on upstream's branch for this distribution (control_msgs jazzy:
#    FollowJointTrajectory.action) lives in interfaces/$DISTRO/<package>/ and replaces its
#    counterpart in a staged copy of the source.
build_interfaces() {  # name source-dir python-import-check
  local name=$1 src=$2 check=$3 over="$ROOT/interfaces/$DISTRO/$1" s build
  shopt -s nullglob  # a package may have no srv/ or action/, and no overlay
  s=$(stamp_of "$src"/CMakeLists.txt "$src"/package.xml "$src"/msg/*.msg "$src"/srv/*.srv \
    "$src"/action/*.action "$over"/*/* "$0")
  shopt -u nullglob
  fresh "msgs-$name" "$s" && return 0
  echo "setup: building $name" >&2
  build="$ROOT/build/$DISTRO/$name"
  rm -rf "$build" "$build-src"; mkdir -p "$(dirname "$build")"
  if [ -d "$over" ]; then
    cp -r "$src" "$build-src" && cp -r "$over"/. "$build-src"/ && src="$build-src"
  fi
  # Fix 2: without AMENT_PREFIX_PATH rosidl finds no typesupport ("No 'rosidl_typesupport_c'").
  # Fix 3: Python3 must be this venv's interpreter, not the system's.
  AMENT_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH" cmake -S "$src" -B "$build" \
    -DBUILD_TESTING=OFF -DCMAKE_PREFIX_PATH="$VENV" -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DPython3_EXECUTABLE="$VPY" -DPYTHON_EXECUTABLE="$VPY" >"$build.log" 2>&1 \
    || { cat "$build.log" >&2; exit 1; }
  AMENT_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH" cmake --build "$build" -j2 >>"$build.log" 2>&1 \
    && cmake --install "$build" >>"$build.log" 2>&1 || { tail -50 "$build.log" >&2; exit 1; }
  "$VPY" -c "$check" || { echo "setup: $name built but does not import" >&2; exit 1; }
  mark "msgs-$name" "$s"
}
[ -f "$VENV/.stamp-msgs" ] || rm -f "$VENV"/.stamp-msgs-*  # the wheels changed: rebuild all
build_interfaces ext_sense_msgs "$ROOT/src/ext_sense_msgs" \
  "from ext_sense_msgs.msg import BioTacFrame, TaxelEventBatch, ContactWindow, ContactEstimate, ContactGroundTruth, SensorPacket"
build_interfaces control_msgs "$ROOT/interfaces/control_msgs" \
  "from control_msgs.action import FollowJointTrajectory, GripperCommand, ParallelGripperCommand"
build_interfaces franka_msgs "$ROOT/interfaces/franka_msgs" \
  "from franka_msgs.msg import FrankaRobotState; from franka_msgs.srv import SetFullCollisionBehavior; from franka_msgs.action import ErrorRecovery"
touch "$VENV/.stamp-msgs"
wait "$TRAIN_PID"

