"""``colcon build`` of ``ros2_ws`` as a ROS user runs it, and the installed tree it leaves.

One real build per test run (``colcon_workspace.build``: ``scripts/build_workspace.sh``, the
script ``make colcon`` and docker/Dockerfile run), shared with test_readme_ros.py, which starts
the README's graph from this installed tree. Here: colcon orders and builds every package of
``src/`` (a circle in the package graph stops it before anything is built, issue 32); a shell
that sourced ``install/setup.bash`` imports every package, messages included, from ``install/``
and not from the checkout; and every node of every graph is an executable where ``ros2 run``
and ``ros2 launch`` look for it, with the launch files where ``ros2 launch`` finds them.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest
from colcon_workspace import (
    ROOT,
    Workspace,
    package_prefix,
    ros2_launch_file,
    ros2_run,
    shared_build,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(900)]

PACKAGES = sorted(p.parent.name for p in (ROOT / "ros2_ws" / "src").glob("*/package.xml"))
GRAPHS = (
    ("tap_localization",),
    ("handover", "behaviours:=true"),
    ("food_identification", "behaviours:=true"),
)
"""Each graph with every node it can start (the behaviours' too)."""
NODE_LINE = re.compile(r"^\S+: (\w+)/(\w+)( \(required\))?$", re.MULTILINE)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory, pytestconfig) -> Workspace:
    return shared_build(tmp_path_factory, pytestconfig)


def test_colcon_builds_every_package_of_the_workspace(workspace):
    assert Path(ROOT / "ros2_ws" / "src").resolve() == ROOT / "src"
    assert len(PACKAGES) >= 8, PACKAGES
    finished = re.findall(r"^Finished <<< (\S+)", workspace.output, re.MULTILINE)
    assert sorted(finished) == PACKAGES, workspace.output[-3000:]
    assert (workspace.install / "setup.bash").is_file()
    for pkg in PACKAGES:
        assert package_prefix(workspace.env, pkg) == workspace.install / pkg


def test_the_sourced_shell_imports_every_package_from_the_installed_tree(workspace):
    code = (
        "import importlib, json\n"
        "from rclpy.serialization import deserialize_message, serialize_message\n"
        "from ext_sense_msgs.msg import ContactEstimate\n"
        f"names = {PACKAGES!r}\n"
        "where = {n: importlib.import_module(n).__file__ for n in names}\n"
        "msg = ContactEstimate(model_id='m', tap_position_m=0.035)\n"
        "back = deserialize_message(serialize_message(msg), ContactEstimate)\n"
        "print(json.dumps({'where': where, 'value': back.tap_position_m}))\n"
    )
    out = subprocess.run(
        ["python", "-c", code],
        cwd=workspace.install.parent,
        env=workspace.env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    found = json.loads(out.stdout)
    assert found["value"] == 0.035
    for name, path in found["where"].items():
        assert Path(path).is_relative_to(workspace.install / name), (name, path)


@pytest.mark.parametrize("graph", GRAPHS, ids=lambda g: g[0])
def test_every_node_and_launch_file_is_where_ros2_finds_it(workspace, graph):
    """What ``ros2 launch ext_sense GRAPH.launch.py`` would start, from the installed tree."""
    ros2_launch_file(workspace.env, "ext_sense", f"{graph[0]}.launch.py")
    exe = ros2_run(workspace.env, "ext_sense", "ext-sense")
    assert exe.is_relative_to(workspace.install)
    out = subprocess.run(
        [str(exe), "run", *graph, "--dry-run"],
        env=workspace.env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    nodes = NODE_LINE.findall(out.stdout)
    assert len(nodes) >= 4, out.stdout
    for package, executable, _ in nodes:
        assert ros2_run(workspace.env, package, executable).is_relative_to(workspace.install)
