"""The ext_sense topics a bag usually holds, with their types and the QoS they are offered with."""

from __future__ import annotations

from typing import NamedTuple


class TopicSpec(NamedTuple):
    """One topic: its type and how it is offered (recorded into the bag for ``ros2 bag play``)."""

    msgtype: str
    reliable: bool
    depth: int


STANDARD_TOPICS: dict[str, TopicSpec] = {
    "/extsense/nuskin/packets": TopicSpec("ext_sense_msgs/msg/SensorPacket", False, 1000),
    "/extsense/biotac/packets": TopicSpec("ext_sense_msgs/msg/SensorPacket", False, 1000),
    "/extsense/nuskin/events": TopicSpec("ext_sense_msgs/msg/TaxelEventBatch", False, 1000),
    "/extsense/biotac/frames": TopicSpec("ext_sense_msgs/msg/BioTacFrame", False, 1000),
    "/extsense/contact_window": TopicSpec("ext_sense_msgs/msg/ContactWindow", True, 20),
    "/extsense/contact_estimate": TopicSpec("ext_sense_msgs/msg/ContactEstimate", True, 50),
    "/extsense/contact_estimate/provisional": TopicSpec(
        "ext_sense_msgs/msg/ContactEstimate", True, 50
    ),
    "/extsense/ground_truth": TopicSpec("ext_sense_msgs/msg/ContactGroundTruth", True, 1000),
    "/diagnostics": TopicSpec("diagnostic_msgs/msg/DiagnosticArray", True, 10),
}
"""Topic name -> spec, as in docs/conventions.md; sensor streams are best effort. ``ext-sense
record`` records every topic here by default; the decoded arrays are in bags from before packets
(``ext-sense bag migrate`` turns those into packet bags)."""
