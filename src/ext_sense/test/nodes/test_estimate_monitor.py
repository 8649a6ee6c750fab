"""The estimate monitor without ground truth (a sensor on a serial port): each final estimate is
printed as it comes, and after ``expected`` of them the summary, then the monitor ends its
process (the runner then stops the graph); provisional estimates are on a topic it reads only
when asked to."""

from __future__ import annotations

import math
import os
import re
import time

import pytest

from ext_sense.nodes.scoreboard import Scoreboard
from ext_sense_runtime.records import Estimate
from ext_sense_runtime.stamps import MS

NS = f"/monitor_test_{os.getpid()}"
"""A namespace of this test's own: other tests' graphs on the machine are not heard."""


def _estimate(i: int, *, provisional: bool = False, degraded: bool = False) -> Estimate:
    return Estimate(
        "tap_localization",
        1_000_000_000 * (i + 1),
        provisional=provisional,
        tap_position_m=0.10 + 0.01 * i,
        tap_position_std_m=0.02,
        compute_latency_ns=(2 + i) * MS,
        degraded=degraded,
        degraded_reason="late packet" if degraded else "",
    )


def test_a_scoreboard_without_ground_truth_counts_and_prints_every_final_estimate():
    board = Scoreboard("tap_localization", ground_truth=False)
    assert board.add_estimate(_estimate(0, provisional=True)) == []
    assert board.add_estimate(_estimate(0)) == [
        "tap   1: estimate  10.00 cm ± 2.00 | latency 2.00 ms"
    ]
    assert board.add_estimate(_estimate(1, degraded=True)) == [
        "tap   2: estimate  11.00 cm ± 2.00 | latency 3.00 ms | DEGRADED (late packet)"
    ]
    assert board.scored == 2
    assert board.provisional_seen == 1
    assert board.summary() == (
        "summary: estimates=2 degraded=1 compute_p50_ms=2.00 compute_p99_ms=2.00 (no ground truth)"
    )


def test_a_classification_scoreboard_without_ground_truth_names_the_class():
    board = Scoreboard("handover_stability", ground_truth=False)
    est = Estimate("handover_stability", 1, stability_probability=0.8, compute_latency_ns=MS)
    assert board.add_estimate(est) == ["trial   1: estimate stable       | latency 1.00 ms"]
    assert math.isclose(board.latencies_ns[0], MS)


@pytest.mark.ros
def test_without_ground_truth_the_monitor_prints_each_estimate_and_ends_after_expected(capfd):
    pytest.importorskip("rclpy")
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rosutil import spinning, wait_for

    from ext_sense.nodes.estimate_monitor import EstimateMonitorNode
    from ext_sense_msgs.msg import ContactEstimate
    from ext_sense_runtime.qos import ESTIMATE_QOS
    from ext_sense_runtime.stamps import fill_stamp

    def monitor(context):
        return EstimateMonitorNode(
            context=context,
            cli_args=["--ros-args", "-r", f"__ns:={NS}"],
            parameter_overrides=[
                Parameter("expected", value=3),
                Parameter("ground_truth", value=False),
            ],
        )

    with spinning(monitor, lambda context: Node("source", namespace=NS, context=context)) as (
        node,
        source,
    ):
        finals = source.create_publisher(ContactEstimate, "contact_estimate", ESTIMATE_QOS)
        anytime = source.create_publisher(
            ContactEstimate, "contact_estimate/provisional", ESTIMATE_QOS
        )
        assert wait_for(lambda: finals.get_subscription_count() == 1, 10.0)
        assert anytime.get_subscription_count() == 0  # show_provisional is false: not read
        for i in range(3):
            msg = ContactEstimate(task="tap_localization", sensor="nuskin")
            fill_stamp(msg.header.stamp, time.time_ns())
            msg.tap_position_m, msg.tap_position_std_m = 0.1 + 0.05 * i, 0.02
            msg.stability_probability = float("nan")
            fill_stamp(msg.compute_latency, 3 * MS)
            finals.publish(msg)
        assert wait_for(lambda: not node.context.ok(), 10.0)  # it ended its process
    out = capfd.readouterr().out.splitlines()
    taps = [line for line in out if line.startswith("tap ")]
    assert [t.split("|")[0].strip() for t in taps] == [
        "tap   1: estimate  10.00 cm ± 2.00",
        "tap   2: estimate  15.00 cm ± 2.00",
        "tap   3: estimate  20.00 cm ± 2.00",
    ]
    assert re.fullmatch(
        r"summary: estimates=3 degraded=0 compute_p50_ms=3\.00 compute_p99_ms=3\.00 "
        r"\(no ground truth\)",
        out[-1],
    ), out
