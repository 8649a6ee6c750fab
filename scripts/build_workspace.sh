#!/usr/bin/env bash
# Build the colcon workspace ros2_ws/ (its src/ is a link to ../src) on a ROS 2 install.
# Used by docker/Dockerfile and by `make colcon` (with the venv's ROS wheels), so the build
# steps exist once.
#
# Environment: PYTHON (default python3), INSTALL_PYTHON_DEPS=1 to pip-install
# requirements/python.txt first (the Docker image does; the venv already has them),
# PIP_ARGS extra pip arguments.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PYTHON=${PYTHON:-python3}

if [ "${INSTALL_PYTHON_DEPS:-0}" = 1 ]; then
  # shellcheck disable=SC2086
  "$PYTHON" -m pip install ${PIP_ARGS:-} -r "$ROOT/requirements/python.txt" \
    -c "$ROOT/requirements/ros-install-constraints.txt"
fi

cd "$ROOT/ros2_ws"
colcon build --event-handlers console_direct- \
  --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$(command -v "$PYTHON")"

# The README's next step is `source install/setup.bash`: colcon writes it only with the
# colcon-bash extension (colcon-common-extensions has it; colcon-core alone writes setup.sh).
if [ ! -f install/setup.bash ]; then
  echo "build_workspace.sh: ros2_ws/install/setup.bash was not written: install colcon-bash" \
    "(pip install colcon-bash, or apt install python3-colcon-bash)" >&2
  exit 1
fi
