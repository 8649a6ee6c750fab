"""A stop signal to ``ext-sense run``'s runner alone ends the whole graph, and leaves no node.

SIGHUP (a closed terminal), SIGQUIT, SIGTERM and SIGINT sent to the runner's process alone, not
its group, stop every node as a Ctrl-C does: each node process exits 0, none is left running
without its supervisor, and no node is left in the ROS graph (``ros2 node list``) 3 s after
the runner exited (``LEAVE_S``): each process destroys its nodes and its context, so its
participant leaves at once instead of when its lease runs out. A runner killed outright
(SIGKILL, no handler) still takes its nodes with it (``PR_SET_PDEATHSIG``). Each test names
its nodes apart, so a participant left to its lease fails only the test that left it, with the
runner's output.

The graph: a lifecycle sensor driver (configured, no device: it retries), the estimate monitor
and the tap marker, each a process of its own, in the test run's ROS domain (conftest.py).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from rosutil import wait_for
from sim_models import STOP_LIMIT_S

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(120)]
"""A graph of node processes whose leave is timed: the graph lane, alone on the machine (in the
parallel lane a clean leave was seen 3 s late twice: the probe's view of discovery under load)."""

TAG = f"sig{os.getpid()}"
LEAVE_S = 3.0
"""How soon a stopped node's participant must be gone from the probe's graph: far under the
15-19 s of a lease running out (what a node that never destroys its context leaves behind); the
suite's parallel lane once delayed the probe's view of a clean leave past 1 s."""


def _names_of(tag: str) -> set[str]:
    return {f"{tag}_driver", f"{tag}_monitor", f"{tag}_marker"}


RUNNER = """
import sys
from ext_sense.graph import ArgumentSpec, GraphSpec, NodeSpec
from ext_sense.runner import run_graph

tag, port = sys.argv[1], sys.argv[2]
NODES = (
    NodeSpec(
        "ext_sense_drivers",
        "nuskin_driver",
        f"{tag}_driver",
        "ext_sense_drivers.nodes.nuskin_driver:NuskinDriverNode",
        {"port": port, "autostart": False},  # the runner configures and activates it
        lifecycle=True,
    ),
    NodeSpec(
        "ext_sense",
        "estimate_monitor",
        f"{tag}_monitor",
        "ext_sense.nodes.estimate_monitor:EstimateMonitorNode",
        {"expected": 0},
    ),
    NodeSpec(
        "ext_sense_behaviours",
        "tap_marker",
        f"{tag}_marker",
        "ext_sense_behaviours.nodes.tap_marker:TapMarkerNode",
    ),
)
USE_SIM_TIME = ArgumentSpec("use_sim_time", "false", "Use /clock.", ("true", "false"))
graph = GraphSpec("signals", "Three nodes, no device.", (USE_SIM_TIME,), lambda values: NODES)
sys.exit(run_graph(graph, {}))
"""


@pytest.fixture(scope="module")
def graph_probe() -> Iterator[object]:
    """A plain node, to read the graph's node names."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, args=[])
    node = rclpy.create_node(f"{TAG}_probe", context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _names(probe, tag: str) -> set[str]:
    names = _names_of(tag)
    return {name for name, _ in probe.get_node_names_and_namespaces() if name in names}


def _assert_left(probe, tag: str, since: float, err: str) -> None:
    """No node of ``tag`` is in the probe's graph ``LEAVE_S`` after ``since``.

    Each test has its own tag, so a participant one test leaves behind fails that test alone.
    """
    wait_for(lambda: not _names(probe, tag), LEAVE_S)
    left = _names(probe, tag)
    assert not left, (
        f"{sorted(left)} still in the graph {time.monotonic() - since:.1f} s on: {err[-3000:]}"
    )


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@contextmanager
def _runner(tmp_path, tag: str) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen(
        [sys.executable, "-c", RUNNER, tag, str(tmp_path / "no_device")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own group: what outlives the runner is still found
    )
    try:
        yield proc
    finally:
        if _group_alive(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)


@pytest.mark.parametrize(
    "signum",
    [signal.SIGHUP, signal.SIGQUIT, signal.SIGTERM, signal.SIGINT],
    ids=lambda s: s.name,
)
def test_a_stop_signal_to_the_runner_alone_ends_every_node_and_leaves_none(
    signum, graph_probe, tmp_path
):
    tag = f"{TAG}_{signum.name.lower()}"
    with _runner(tmp_path, tag) as proc:
        started = wait_for(lambda: _names(graph_probe, tag) == _names_of(tag), 60.0)
        assert started, _names(graph_probe, tag)
        time.sleep(0.5)  # the lifecycle driver configured and activated
        os.kill(proc.pid, signum)  # the runner alone, not its group
        _, err = proc.communicate(timeout=STOP_LIMIT_S + 5)
        exited = time.monotonic()
        assert proc.returncode == 0, err[-3000:]
        assert not _group_alive(proc.pid), "a node outlived its runner"
        _assert_left(graph_probe, tag, exited, err)
    codes = next(line for line in err.splitlines() if line.startswith("[run] exit codes:"))
    expected = {f"{name}=0" for name in _names_of(tag)}
    assert set(codes.split(":", 1)[1].split()) == expected, err[-2000:]
    assert "Traceback" not in err, err[-3000:]


def test_a_runner_killed_outright_takes_its_nodes_with_it(graph_probe, tmp_path):
    tag = f"{TAG}_sigkill"
    with _runner(tmp_path, tag) as proc:
        started = wait_for(lambda: _names(graph_probe, tag) == _names_of(tag), 60.0)
        assert started, _names(graph_probe, tag)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        assert wait_for(lambda: not _group_alive(proc.pid), STOP_LIMIT_S), "orphaned nodes"
        gone = time.monotonic()
        err = proc.stderr.read() if proc.stderr else ""
        _assert_left(graph_probe, tag, gone, err)
