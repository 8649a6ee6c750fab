"""A node process that does not stop on SIGINT is killed, and the log first says where it hung.

``ext-sense run`` gives each node ``STOP_GRACE_S`` after SIGINT; one still running then gets
``STACKS_SIGNAL`` (``node_main`` prints every thread's stack on it) before SIGKILL, so a hang
at shutdown (seen once in a ``make test`` run: ``estimate_monitor did not stop within 5 s``)
leaves evidence instead of only an exit code of -9.
"""

from __future__ import annotations

import io
import signal
import subprocess
import sys
import time

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


def test_a_node_that_ignores_the_stop_prints_its_stacks_then_is_killed(monkeypatch):
    monkeypatch.setattr(runner, "STOP_GRACE_S", 0.5)
    proc = subprocess.Popen(
        [sys.executable, "-c", HUNG_NODE],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline().strip() == "ready"
        log = io.StringIO()
        t0 = time.monotonic()
        codes = runner.stop_nodes({"hung": proc}, log)
        took = time.monotonic() - t0
        stderr = proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert codes == {"hung": -signal.SIGKILL}
    assert "hung did not stop within 0.5 s" in log.getvalue()
    assert "stuck_in_a_callback" in stderr, stderr  # the stack of the main thread
    assert took < 0.5 + runner.STACKS_WAIT_S + 2.0
