"""The colcon workspace ``ros2_ws/`` built as a ROS user builds it, once per test run, and the
environment of a shell that then sourced its ``install/setup.bash``.

The build is ``scripts/build_workspace.sh`` (``cd ros2_ws && colcon build``, as ``make colcon``
and docker/Dockerfile run it) with the colcon that ``scripts/setup.sh`` installs beside the venv,
the venv's ROS standing for a sourced ``/opt/ros``, into a directory of the test run's own
(``COLCON_BASE``), never the checkout's ``ros2_ws/{build,install,log}``. The tests that need the
installed tree (test_colcon_workspace.py, test_readme_ros.py) share one build: :func:`build` is
memoised on the base directory, and both take theirs from pytest's session temporary directory.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import NamedTuple

import pytest

ROOT = Path(__file__).resolve().parents[1]
VENV = Path(sys.prefix)
BUILD_TIMEOUT_S = 600


class Workspace(NamedTuple):
    """A built workspace: where it is installed, what colcon said, how long it took."""

    install: Path
    output: str
    seconds: float
    env: dict[str, str]  # a shell's environment after ``source install/setup.bash``


def ros_env() -> dict[str, str]:
    """This environment as after ``source /opt/ros/<distro>/setup.bash``: the venv is the ROS."""
    env = dict(os.environ)
    env["PATH"] = f"{VENV / 'bin'}:{env.get('PATH', '')}"
    prefixes = [p for p in env.get("AMENT_PREFIX_PATH", "").split(":") if p and p != str(VENV)]
    env["AMENT_PREFIX_PATH"] = ":".join([*prefixes, str(VENV)])
    env.pop("PYTHONPATH", None)
    return env


def build(base: Path) -> Workspace:
    """Build ``ros2_ws`` into ``base/{build,install,log}`` and source the result, once per base
    directory (a failed build fails every later call too, without building again).

    Raises:
        AssertionError: no colcon beside the venv, or the build failed (with colcon's output).
    """
    if base not in _BUILDS:
        _BUILDS[base] = _build(base)
    ws = _BUILDS[base]
    assert isinstance(ws, Workspace), ws
    return ws


_BUILDS: dict[Path, Workspace | str] = {}
"""Each base directory's workspace, or why its build failed."""


def _build(base: Path) -> Workspace | str:
    colcon = VENV / "bin" / "colcon"
    if not colcon.is_file():
        return f"{colcon} is missing: scripts/setup.sh installs it (make setup)"
    env = ros_env()
    env.update(COLCON_BASE=str(base), COLCON_WORKERS="2", PYTHON=str(VENV / "bin" / "python"))
    t0 = time.monotonic()
    try:
        done = subprocess.run(
            [str(ROOT / "scripts" / "build_workspace.sh")],
            env=env,
            capture_output=True,
            text=True,
            timeout=BUILD_TIMEOUT_S,
        )
    except subprocess.TimeoutExpired as err:
        return f"colcon build did not finish in {BUILD_TIMEOUT_S} s:\n{str(err.stdout)[-6000:]}"
    seconds = time.monotonic() - t0
    output = done.stdout + done.stderr
    if done.returncode != 0:
        return f"colcon build failed ({done.returncode}):\n{output[-6000:]}"
    install = base / "install"
    return Workspace(install, output, seconds, sourced(install / "setup.bash", ros_env()))


def shared_build(tmp_path_factory: pytest.TempPathFactory, config: pytest.Config) -> Workspace:
    """The test run's one build (:func:`build` in its session temporary directory).

    The first call builds, and says so in the test run's output (CI's log): the packages and
    the seconds they took.
    """
    base = tmp_path_factory.getbasetemp() / "colcon"
    first = base not in _BUILDS
    ws = build(base)
    plugins = config.pluginmanager
    reporter, capture = plugins.get_plugin("terminalreporter"), plugins.get_plugin("capturemanager")
    if first and reporter is not None and capture is not None:
        finished = re.findall(r"^Finished <<< (\S+) \[([^\]]+)\]", ws.output, re.MULTILINE)
        with capture.global_and_fixture_disabled():
            reporter.write_line(
                f"\ncolcon build of ros2_ws: {len(finished)} packages in {ws.seconds:.1f} s "
                f"({', '.join(f'{p} {s}' for p, s in finished)}); installed in {ws.install}"
            )
    return ws


def sourced(script: Path, env: dict[str, str]) -> dict[str, str]:
    """The environment of a bash that ran ``source SCRIPT`` in ``env``."""
    out = subprocess.run(
        ["bash", "-c", 'source "$1" >/dev/null && env -0', "bash", str(script)],
        env=env,
        capture_output=True,
        check=True,
        timeout=60,
    ).stdout.decode()
    return dict(item.split("=", 1) for item in out.split("\0") if "=" in item)


def package_prefix(env: dict[str, str], package: str) -> Path:
    """The prefix ``ros2`` finds a package in: the first on ``AMENT_PREFIX_PATH`` whose ament
    index registers it (``ament_index_python.get_package_prefix``)."""
    for prefix in filter(None, env.get("AMENT_PREFIX_PATH", "").split(":")):
        if (
            Path(prefix) / "share" / "ament_index" / "resource_index" / "packages" / package
        ).is_file():
            return Path(prefix)
    raise AssertionError(f"package {package!r} not found on AMENT_PREFIX_PATH")


def ros2_run(env: dict[str, str], package: str, executable: str) -> Path:
    """What ``ros2 run PACKAGE EXECUTABLE`` runs: ``<prefix>/lib/<package>/<executable>``."""
    path = package_prefix(env, package) / "lib" / package / executable
    assert os.access(path, os.X_OK), f"{package} installs no executable {path}"
    return path


def ros2_launch_file(env: dict[str, str], package: str, launch_file: str) -> Path:
    """The file ``ros2 launch PACKAGE LAUNCH_FILE`` loads, from ``<prefix>/share/<package>``."""
    path = package_prefix(env, package) / "share" / package / "launch" / launch_file
    assert path.is_file(), f"{package} installs no launch file {path}"
    return path
