"""QoS profiles of ext_sense, chosen on purpose and named for what they carry.

- Raw tactile streams: best effort like ``qos_profile_sensor_data`` (a late sample is
  worthless, a retransmission adds latency), but deep: 1000 packets ride out a 0.25 s burst at
  4 kHz (``bench/bench_runtime.py --only worst``).
- Windows, estimates and commands: reliable with an explicit depth; rare, and each matters.
  Volatile, so late joiners do not act on a stale contact.
- Behaviour decisions: reliable and transient local, the last 20 kept: a decision is a log
  line, not a command, so a late joiner (an operator's echo, a view, a test's recorder matched
  after the behaviour's first step) is shown how the behaviour reached its state instead of
  missing its first decisions.
- Ground truth: reliable, deep (one per trial, recorded beside the data). Subscribers ask for
  volatile, which matches any publisher; the simulated device offers transient local
  (``GROUND_TRUTH_OFFERED_QOS``), so a subscriber that asks for it (a test's recorder matched
  after the first trial) gets the trials it joined too late for.
- Diagnostics: reliable, depth 10, as diagnostic_aggregator expects.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def keep_last(depth: int, reliable: bool, latched: bool = False) -> QoSProfile:
    """A keep-last profile of ``depth``, reliable or best effort, volatile unless ``latched``."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


SENSOR_STREAM_QOS = keep_last(1000, reliable=False)
WINDOW_QOS = keep_last(20, reliable=True)
ESTIMATE_QOS = keep_last(50, reliable=True)
COMMAND_QOS = keep_last(10, reliable=True)
DECISION_QOS = keep_last(20, reliable=True, latched=True)
GROUND_TRUTH_QOS = keep_last(1000, reliable=True)
GROUND_TRUTH_OFFERED_QOS = keep_last(1000, reliable=True, latched=True)
DIAGNOSTICS_QOS = keep_last(10, reliable=True)
