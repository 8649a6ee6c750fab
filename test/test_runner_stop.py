"""A node process that does not stop on SIGINT: the log says where it hung, and it ends.

- ``ext-sense run`` gives each node ``STOP_GRACE_S`` after SIGINT; one still running then gets
  ``STACKS_SIGNAL`` (``node_main`` prints every thread's stack on it) before SIGKILL, so a hang
  at shutdown leaves evidence instead of only an exit code of -9.
- ``teardown_guard.TeardownGuard``: a hang inside rclpy while the last node is destroyed (what
  the stacks showed in ``test_shutdown`` runs: the middleware destroying ``sim_device`` or
  ``estimate_monitor``, holding the GIL) ends the process with 0 after ``TEARDOWN_LIMIT_S``; a
  hang in a node's own cleanup does not.
"""

from __future__ import annotations

import contextlib
import io
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from ext_sense import runner
from ext_sense_runtime.teardown_guard import TEARDOWN_LIMIT_S

HUNG_NODE = """
import sys, time
from ext_sense_runtime.stop import install_stop_handlers

def stuck_in_a_callback():
    while True:  # a stop request is recorded, never looked at
        time.sleep(0.01)

install_stop_handlers()
print("ready", flush=True)
stuck_in_a_callback()
"""


@contextlib.contextmanager
def started(script: str, *args: str) -> Iterator[subprocess.Popen[str]]:
    """``python -c script args`` once it printed "ready"; killed on the way out if still running."""
    proc = subprocess.Popen(
        [sys.executable, "-c", script, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline().strip() == "ready"
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_a_node_that_ignores_the_stop_prints_its_stacks_then_is_killed(monkeypatch):
    monkeypatch.setattr(runner, "STOP_GRACE_S", 0.5)
    with started(HUNG_NODE) as proc:
        log = io.StringIO()
        t0 = time.monotonic()
        codes = runner.stop_nodes({"hung": proc}, log)
        took = time.monotonic() - t0
        stderr = proc.stderr.read()
    assert codes == {"hung": -signal.SIGKILL}
    assert "hung did not stop within 0.5 s" in log.getvalue()
    assert "stuck_in_a_callback" in stderr, stderr  # the stack of the main thread
    assert took < 0.5 + runner.STACKS_WAIT_S + 2.0


STUCK_AT_TEARDOWN = """
import ctypes, sys
from rclpy.node import Node
from ext_sense_runtime.node_main import run_nodes

WHERE = sys.argv[1]


def hang():
    # a C call that keeps the GIL (a PyDLL function), as the middleware's destruction did: no
    # Python thread can run while it blocks
    ctypes.PyDLL(None).sleep(60)


class Stuck(Node):
    def __init__(self):
        super().__init__("stuck")
        print("ready", flush=True)

    def destroy_node(self):
        if WHERE == "own":
            hang()  # the node's own cleanup never ends
        # the middleware's destruction, inside rclpy's destroy_node, never ends
        self._type_description_service.destroy = hang
        super().destroy_node()


sys.exit(run_nodes([Stuck], args=[]))
"""


def _stop_stuck(where: str, wait_s: float) -> tuple[int | None, str, float]:
    """Start a node stuck at teardown ``where``, SIGINT it, wait; (exit code or None, stderr)."""
    with started(STUCK_AT_TEARDOWN, where) as proc:
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(timeout=wait_s)
        except subprocess.TimeoutExpired:
            code = None
        took = time.monotonic() - t0
    return code, proc.stderr.read(), took


def test_a_hang_holding_the_gil_in_the_middleware_teardown_of_the_last_node_ends_the_process():
    code, stderr, took = _stop_stuck("rclpy", TEARDOWN_LIMIT_S + 4.0)
    assert code == 0, stderr
    assert f"Timeout (0:00:0{TEARDOWN_LIMIT_S:g})!" in stderr  # faulthandler's stacks
    assert "in hang" in stderr, stderr
    assert "in destroy_node" in stderr, stderr
    assert "[stuck] rclpy's teardown hung for 3 s after every node's own cleanup" in stderr
    assert TEARDOWN_LIMIT_S <= took < TEARDOWN_LIMIT_S + 4.0


def test_a_hang_holding_the_gil_in_a_node_own_cleanup_is_left_to_the_supervisor():
    code, stderr, _ = _stop_stuck("own", TEARDOWN_LIMIT_S + 1.5)
    assert code is None, stderr  # still running: its own cleanup may be writing data
    assert f"Timeout (0:00:0{TEARDOWN_LIMIT_S:g})!" in stderr  # its stacks are out
    assert "in hang" in stderr, stderr
    assert "rclpy's teardown hung" not in stderr


@pytest.mark.ros
def test_a_guarded_teardown_that_ends_in_time_leaves_no_trace():
    import rclpy
    from rclpy.node import Node

    from ext_sense_runtime.teardown_guard import TeardownGuard

    context = rclpy.Context()
    rclpy.init(context=context, args=[])
    nodes = [Node("first", context=context), Node("last", context=context)]
    with TeardownGuard(nodes) as guard:
        for node in nodes:
            guard.destroying(node)
            node.destroy_node()
        guard.destroying(None)
        with guard.middleware():
            rclpy.try_shutdown(context=context)
    assert guard.armed == 2  # around rclpy's destroy_node of the last node, and its shutdown
    time.sleep(TEARDOWN_LIMIT_S + 0.5)  # both timers deleted: this process is still here
