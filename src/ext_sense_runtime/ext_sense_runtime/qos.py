"""QoS profiles of ext_sense, chosen on purpose and named for what they carry.

- Raw tactile streams: best effort like ``qos_profile_sensor_data`` (a late sample is
  worthless, a retransmission adds latency), but deep: 1000 packets ride out a 0.25 s burst at
  4 kHz (``bench/bench_runtime.py --only worst``).
- Windows, estimates and commands: reliable with an explicit depth; rare, and each matters.
  Volatile, so late joiners do not act on a stale contact.
- Ground truth: reliable, deep (one per trial, recorded beside the data).
- Diagnostics: reliable, depth 10, as diagnostic_aggregator expects.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def _keep_last(depth: int, reliability: ReliabilityPolicy) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=reliability,
        durability=DurabilityPolicy.VOLATILE,
    )


SENSOR_STREAM_QOS = _keep_last(1000, ReliabilityPolicy.BEST_EFFORT)
WINDOW_QOS = _keep_last(20, ReliabilityPolicy.RELIABLE)
ESTIMATE_QOS = _keep_last(50, ReliabilityPolicy.RELIABLE)
COMMAND_QOS = _keep_last(10, ReliabilityPolicy.RELIABLE)
GROUND_TRUTH_QOS = _keep_last(1000, ReliabilityPolicy.RELIABLE)
DIAGNOSTICS_QOS = _keep_last(10, ReliabilityPolicy.RELIABLE)
