"""A node process started through ``run_node`` ends cleanly on SIGINT and SIGTERM."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.ros

CHILD = """
import sys
from rclpy.node import Node
from ext_sense_runtime.node_main import run_node

class Ticker(Node):
    def __init__(self, **kwargs):
        super().__init__("ticker", **kwargs)
        self.create_timer(0.05, lambda: None)
        print("ready", flush=True)

sys.exit(run_node(Ticker, []))
"""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_node_process_stops_on_signal(signum):
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "ready"
        time.sleep(0.3)
        child.send_signal(signum)
        rc = child.wait(timeout=10)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert rc == 0, child.stderr.read()
