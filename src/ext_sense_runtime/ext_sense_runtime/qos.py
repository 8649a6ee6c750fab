"""QoS profiles of ext_sense, chosen on purpose and named for what they carry.

- Raw tactile streams (event batches, BioTac frames): best effort like
  ``qos_profile_sensor_data`` (a late sample is worthless, and retransmission would add
  latency), but a deep history: at 4 kHz a burst of 1000 batches is 0.25 s, enough for no
  drop at the worst-case input (``bench/bench_runtime.py --only worst``).
- Contact windows, estimates and commands: reliable with an explicit depth; each is rare and
  each matters. Estimates are transient-local-free so late joiners do not act on stale contact.
- Ground truth: reliable, deep (one per trial, recorded beside the data).
- Diagnostics: reliable, depth 10, as diagnostic_aggregator expects.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

SENSOR_STREAM_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)

RELIABLE_STREAM_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""For recording and replay, where a subscriber must see every batch."""

WINDOW_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=20,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

ESTIMATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=50,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

GROUND_TRUTH_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

DIAGNOSTICS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
