"""Intra-process delivery: handed over in the publisher's call, each message exactly once.

Three nodes in one context on one executor, as a node group runs them: ``talker`` publishes
intra-process, ``other`` publishes plainly (as a bag player or another process would), and
``listener`` subscribes intra-process to the same topic.
"""

from __future__ import annotations

import time

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")

from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.subscription import Subscription  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from ext_sense_runtime import intra_process  # noqa: E402
from ext_sense_runtime.executor import make_executor  # noqa: E402

QOS = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)


def _spin_for(executor, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.01)


@pytest.fixture
def graph(monkeypatch):
    monkeypatch.setattr(intra_process, "_enabled", True)
    context = rclpy.Context()
    rclpy.init(context=context)
    talker = rclpy.create_node("talker", context=context)
    other = rclpy.create_node("other", context=context)
    listener = rclpy.create_node("listener", context=context)
    executor = make_executor(context=context)
    for node in (talker, other, listener):
        executor.add_node(node)
    try:
        yield talker, other, listener, executor
    finally:
        executor.shutdown()
        for node in (talker, other, listener):
            node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_local_messages_are_handed_over_at_once_and_their_middleware_copies_dropped(graph):
    talker, other, listener, executor = graph
    got: list[str] = []
    sub = intra_process.create_subscription(
        listener, String, "chatter", lambda m: got.append(m.data), QOS
    )
    local = intra_process.create_publisher(talker, String, "chatter", QOS)
    plain = other.create_publisher(String, "chatter", QOS)
    assert isinstance(sub, intra_process.IntraProcessSubscription)
    assert isinstance(local, intra_process.IntraProcessPublisher)
    assert local.topic_name == "/chatter"  # the rclpy publisher's attributes pass through
    _spin_for(executor, 0.3)  # discovery, so the middleware copies do come

    for i in range(20):
        local.publish(String(data=f"local {i}"))
        assert got[-1] == f"local {i}"  # in the publish call, before any spin
        plain.publish(String(data=f"remote {i}"))
        _spin_for(executor, 0.01)
    _spin_for(executor, 1.0)  # every middleware copy has time to come

    assert sorted(got) == sorted(
        [f"local {i}" for i in range(20)] + [f"remote {i}" for i in range(20)]
    )
    assert (sub.local, sub.remote, sub.duplicates) == (20, 20, 20)


def test_a_subscription_of_a_destroyed_node_is_no_longer_called(graph):
    talker, _other, listener, _executor = graph
    got: list[str] = []
    intra_process.create_subscription(
        listener, String, "chatter", lambda m: got.append(m.data), QOS
    )
    local = intra_process.create_publisher(talker, String, "chatter", QOS)
    local.publish(String(data="before"))
    listener.destroy_node()
    local.publish(String(data="after"))
    assert got == ["before"]


def test_without_enable_the_entities_are_plain_rclpy_ones(graph, monkeypatch):
    talker, _other, listener, _executor = graph
    monkeypatch.setattr(intra_process, "_enabled", False)
    sub = intra_process.create_subscription(listener, String, "chatter", lambda m: None, QOS)
    pub = intra_process.create_publisher(talker, String, "chatter", QOS)
    assert type(sub) is Subscription
    assert not isinstance(pub, intra_process.IntraProcessPublisher)


def test_the_counters_are_diagnostics_values_of_an_intra_process_subscription_only(graph):
    _talker, _other, listener, _executor = graph
    sub = intra_process.create_subscription(listener, String, "chatter", lambda m: None, QOS)
    assert intra_process.delivery_values(sub, "input") == {
        "input_in_process": 0,
        "input_from_middleware": 0,
        "input_middleware_copies_dropped": 0,
    }
    plain = listener.create_subscription(String, "chatter", lambda m: None, QOS)
    assert intra_process.delivery_values(plain, "input") == {}
