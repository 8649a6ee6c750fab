"""The collector lets the simulated device start (by subscribing to its truth) only once the
sensor stream reaches the recording: discovery matches each topic on its own, and a stream that
matched after the first trials left a session bag without their packets."""

from __future__ import annotations

import time

import pytest

pytestmark = pytest.mark.ros


def _truth_subscribers(node) -> set[str]:
    from ext_sense.collect.graph import SIM_TRUTH_TOPIC

    return {i.node_name for i in node.get_subscriptions_info_by_topic(SIM_TRUTH_TOPIC)}


def test_the_truth_subscription_waits_for_the_stream_to_match(tmp_path):
    import rclpy
    from rclpy.context import Context
    from rosutil import spin_until

    from ext_sense.collect.graph import COLLECTOR_NODE, MATCH_SETTLE_S
    from ext_sense.collect.node import CollectorNode
    from ext_sense.topics import TOPIC_NUSKIN_PACKETS
    from ext_sense_bags import BagWriter
    from ext_sense_msgs.msg import SensorPacket
    from ext_sense_runtime.executor import make_executor
    from ext_sense_runtime.qos import keep_last

    context = Context()
    rclpy.init(context=context, args=[])
    executor = make_executor(context=context)
    writer = BagWriter(tmp_path / "bag", flush_period_s=1.0).open()
    collector = CollectorNode(writer, TOPIC_NUSKIN_PACKETS, context=context)
    driver = rclpy.create_node("driver_probe", context=context)
    try:
        executor.add_node(collector)
        executor.add_node(driver)
        spin_until(executor, lambda: False, 1.5)  # longer than the settle, no stream yet
        assert COLLECTOR_NODE not in _truth_subscribers(driver)

        driver.create_publisher(SensorPacket, TOPIC_NUSKIN_PACKETS, keep_last(10, reliable=False))
        assert spin_until(executor, lambda: collector.matched_publishers(TOPIC_NUSKIN_PACKETS))
        matched = time.monotonic()
        assert spin_until(executor, lambda: COLLECTOR_NODE in _truth_subscribers(driver))
        assert time.monotonic() - matched >= 0.8 * MATCH_SETTLE_S  # the publisher side's settle
    finally:
        collector.destroy_node()
        driver.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)
        writer.close()
