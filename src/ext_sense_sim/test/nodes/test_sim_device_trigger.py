"""``sim_device`` in trigger mode: silent until a behaviour asks, then plays the asked trials."""

import contextlib
import os
import time

import pytest

pytestmark = pytest.mark.ros


def test_node_plays_a_trial_per_trigger_with_its_onset_at_the_trigger_stamp(tmp_path):
    rclpy = pytest.importorskip("rclpy")
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ext_sense_msgs.msg import ContactGroundTruth
    from ext_sense_runtime.qos import COMMAND_QOS, GROUND_TRUTH_QOS
    from ext_sense_runtime.stamps import fill_stamp, stamp_to_ns
    from ext_sense_sim.nodes.sim_device import SimDeviceNode

    context = rclpy.Context()
    rclpy.init(context=context)
    link = tmp_path / "nuskin_port"
    node = peer = None
    fd = None
    try:
        node = SimDeviceNode(
            context=context,
            parameter_overrides=[
                Parameter("scene", value="handover_rod_nuskin"),
                Parameter("port_link", value=str(link)),
                Parameter("mode", value="trigger"),
                Parameter("align", value="onset"),
                Parameter("labels", value="unstable"),
                Parameter("trials", value=0),
            ],
        )
        peer = rclpy.create_node("behaviour", context=context)
        got = []
        peer.create_subscription(ContactGroundTruth, "ground_truth", got.append, GROUND_TRUTH_QOS)
        trigger = peer.create_publisher(ContactGroundTruth, "trigger", COMMAND_QOS)
        fd = os.open(link, os.O_RDONLY | os.O_NONBLOCK)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executor.add_node(peer)

        def spin(seconds: float, until=lambda: False) -> bytes:
            data = b""
            end = time.monotonic() + seconds
            while time.monotonic() < end and not until():
                executor.spin_once(timeout_sec=0.02)
                with contextlib.suppress(BlockingIOError):
                    data += os.read(fd, 65536)
            return data

        # subscriptions matched, and nothing is sent before a trigger
        spin(
            5.0,
            lambda: (
                trigger.get_subscription_count() > 0 and peer.count_publishers("ground_truth") > 0
            ),
        )
        assert spin(0.5) == b""
        assert got == []
        stamp = time.time_ns()
        msg = ContactGroundTruth(task="handover_stability")
        fill_stamp(msg.header.stamp, stamp)
        trigger.publish(msg)
        data = spin(5.0, lambda: bool(got))
        data += spin(0.5)
        assert len(got) == 1
        assert got[0].class_label == "unstable"
        assert stamp_to_ns(got[0].header.stamp) == stamp
        from ext_sense_drivers.nuskin.wire import WordDecoder

        assert WordDecoder().feed(data).taxel.size > 100
    finally:
        if fd is not None:
            os.close(fd)
        for n in (node, peer):
            if n is not None:
                n.destroy_node()
        rclpy.try_shutdown(context=context)
    assert not link.exists()
