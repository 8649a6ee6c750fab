"""A node process started through ``run_node`` ends cleanly on SIGINT and SIGTERM, repeated."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.ros

CHILD = """
import sys, time
from rclpy.node import Node
from ext_sense_runtime.node_main import run_node

class Ticker(Node):
    def __init__(self, **kwargs):
        super().__init__("ticker", **kwargs)
        self.create_timer(0.05, self.tick)
        print("ready", flush=True)

    def tick(self):
        time.sleep(0.04)  # a signal most likely lands inside this callback

    def destroy_node(self):
        print("destroying", flush=True)
        time.sleep(0.3)  # a second signal lands in the cleanup
        super().destroy_node()

sys.exit(run_node(Ticker, []))
"""
CRASH_MARKERS = ("Traceback", "terminate called", "Fatal Python error", "Aborted", "[FATAL]")


@pytest.mark.parametrize(
    "signals",
    [
        [signal.SIGINT],
        [signal.SIGTERM],
        [signal.SIGINT, signal.SIGINT],  # a terminal's Ctrl-C, then the one launch forwards
        [signal.SIGINT, signal.SIGTERM],  # launch escalating
        [signal.SIGINT, signal.SIGINT, signal.SIGINT],
    ],
    ids=lambda sigs: "+".join(s.name for s in sigs),
)
def test_node_process_stops_on_signal(signals):
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "ready"
        time.sleep(0.3)
        child.send_signal(signals[0])
        if signals[1:]:
            assert child.stdout.readline().strip() == "destroying"
            for signum in signals[1:]:
                time.sleep(0.05)
                child.send_signal(signum)
        rc = child.wait(timeout=10)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    err = child.stderr.read()
    assert rc == 0, err
    assert not [line for line in err.splitlines() if any(m in line for m in CRASH_MARKERS)], err
