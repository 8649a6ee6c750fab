#!/usr/bin/env bash
# Build the colcon workspace ros2_ws/ (its src/ is a link to ../src) as a ROS user does:
# `cd ros2_ws && colcon build`, then `source install/setup.bash`. Used by docker/Dockerfile (the
# distribution's colcon on a ROS install), by `make colcon` (the colcon of scripts/setup.sh on
# the venv's ROS wheels) and by the tests that build the workspace (test/colcon_workspace.py),
# so the build steps exist once.
#
# Environment: PYTHON (default python3: the interpreter cmake builds the interfaces for),
# INSTALL_PYTHON_DEPS=1 to pip-install requirements/python.txt first (the Docker image does; the
# venv already has them), PIP_ARGS extra pip arguments, COLCON_BASE where build/, install/ and
# log/ go (default ros2_ws/ itself), COLCON_WORKERS packages built at once (default: colcon's,
# one per core).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PYTHON=${PYTHON:-python3}
BASE=${COLCON_BASE:-$ROOT/ros2_ws}

if [ "${INSTALL_PYTHON_DEPS:-0}" = 1 ]; then
  # shellcheck disable=SC2086
  "$PYTHON" -m pip install ${PIP_ARGS:-} -r "$ROOT/requirements/python.txt" \
    -c "$ROOT/requirements/ros-install-constraints.txt"
fi

if ! command -v colcon >/dev/null; then
  echo "build_workspace.sh: no colcon on PATH (apt install python3-colcon-common-extensions on a" \
    "ROS install; scripts/setup.sh puts one in .venv/bin)" >&2
  exit 1
fi

cd "$ROOT/ros2_ws"
colcon --log-base "$BASE/log" build --build-base "$BASE/build" --install-base "$BASE/install" \
  --event-handlers console_direct- ${COLCON_WORKERS:+--parallel-workers "$COLCON_WORKERS"} \
  --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$(command -v "$PYTHON")"

# The README's next step is `source install/setup.bash`: colcon writes it only with the
# colcon-bash extension (colcon-common-extensions has it; colcon-core alone writes setup.sh).
if [ ! -f "$BASE/install/setup.bash" ]; then
  echo "build_workspace.sh: $BASE/install/setup.bash was not written: install colcon-bash" \
    "(pip install colcon-bash, or apt install python3-colcon-bash)" >&2
  exit 1
fi
