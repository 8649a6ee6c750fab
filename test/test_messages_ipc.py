"""Every ext_sense message type crosses a process boundary intact (publish in a child process,
receive here), which proves the interface package built and its type support loads."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

HERE = Path(__file__).resolve().parent

PUBLISHER = """
import time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from msg_samples import samples
rclpy.init()
node = rclpy.create_node("sample_publisher")
qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
msgs = samples()
pubs = {n: node.create_publisher(type(m), "/extsense_test/" + n, qos) for n, m in msgs.items()}
deadline = time.monotonic() + 20.0
try:
    while time.monotonic() < deadline:
        for name, msg in msgs.items():
            pubs[name].publish(msg)
        time.sleep(0.05)
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""


def test_each_message_type_crosses_processes():
    import rclpy
    from msg_samples import assert_same, samples
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    expected = samples()
    received: dict[str, object] = {}
    context = rclpy.Context()
    rclpy.init(context=context)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]),
    }
    child = subprocess.Popen([sys.executable, "-c", PUBLISHER], env=env)
    node = rclpy.create_node("sample_subscriber", context=context)
    try:
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        for name, msg in expected.items():
            node.create_subscription(
                type(msg),
                "/extsense_test/" + name,
                lambda m, n=name: received.setdefault(n, m),
                qos,
            )
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        executor.add_node(node)
        deadline = time.monotonic() + 20.0
        while len(received) < len(expected) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
            assert child.poll() is None, "publisher process died"
    finally:
        child.terminate()
        child.wait(timeout=10)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    assert set(received) == set(expected)
    for name, msg in expected.items():
        assert_same(msg, received[name])
