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


def keep_last(depth: int, reliable: bool) -> QoSProfile:
    """A volatile keep-last profile of ``depth``, reliable or best effort."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.VOLATILE,
    )


SENSOR_STREAM_QOS = keep_last(1000, reliable=False)
WINDOW_QOS = keep_last(20, reliable=True)
ESTIMATE_QOS = keep_last(50, reliable=True)
COMMAND_QOS = keep_last(10, reliable=True)
GROUND_TRUTH_QOS = keep_last(1000, reliable=True)
DIAGNOSTICS_QOS = keep_last(10, reliable=True)
