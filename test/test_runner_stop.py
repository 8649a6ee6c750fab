"""A node process that does not stop on SIGINT: the log says where it hung, and it ends.

- ``ext-sense run`` gives each node ``STOP_GRACE_S`` after SIGINT; one still running then gets
  ``STACKS_SIGNAL`` (``node_main`` prints every thread's stack on it) before SIGKILL, so a hang
  at shutdown leaves evidence instead of only an exit code of -9.
- ``node_main.TeardownGuard``: a hang inside rclpy while the last node is destroyed (what the
  stacks showed in a ``test_shutdown`` run: the middleware destroying ``sim_device``) ends the
  process with 0 after ``TEARDOWN_LIMIT_S``; a hang in a node's own cleanup does not.
"""

from __future__ import annotations

import contextlib
import io
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

from ext_sense import runner

HUNG_NODE = """
import sys, time
from ext_sense_runtime.node_main import install_stop_handlers

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
import sys, time
import rclpy.node
from rclpy.node import Node
from ext_sense_runtime.node_main import run_nodes

WHERE = sys.argv[1]
ns = {}  # a hang whose innermost Python frame is rclpy's, as the middleware's was
exec(compile("def hang(self):\\n    while True:\\n        time.sleep(0.05)\\n",
             rclpy.node.__file__, "exec"), {"time": time}, ns)


class Stuck(Node):
    def __init__(self):
        super().__init__("stuck")
        print("ready", flush=True)

    def destroy_node(self):
        if WHERE == "own":
            while True:  # the node's own cleanup never ends
                time.sleep(0.05)
        Node._wake_executor = ns["hang"]  # the last step of rclpy's destroy_node
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


def test_a_hang_in_the_middleware_teardown_of_the_last_node_ends_the_process():
    from ext_sense_runtime.node_main import TEARDOWN_LIMIT_S

    code, stderr, took = _stop_stuck("rclpy", TEARDOWN_LIMIT_S + 4.0)
    assert code == 0, stderr
    assert "[stuck] the teardown did not end within" in stderr
    assert "exiting without it" in stderr
    assert "in hang" in stderr  # its stack
    assert TEARDOWN_LIMIT_S <= took < TEARDOWN_LIMIT_S + 4.0


def test_a_hang_in_a_node_own_cleanup_is_left_to_the_supervisor():
    from ext_sense_runtime.node_main import TEARDOWN_LIMIT_S

    code, stderr, _ = _stop_stuck("own", TEARDOWN_LIMIT_S + 1.5)
    assert code is None, stderr  # still running: its own cleanup may be writing data
    assert "[stuck] the teardown did not end within" in stderr  # its stacks are out
    assert "exiting without it" not in stderr
