"""The graphs' topic names, in one place: the graph descriptions, the view and the commands.

Absolute names; a node subscribes to its relative name (``events``, ``window``, ...) and the
graph description remaps it to one of these (:mod:`ext_sense.graphs`). Their message types and
QoS are in :data:`ext_sense_bags.STANDARD_TOPICS`.

Estimates: ``/extsense/contact_estimate`` carries the final estimate of each contact alone (one
message per contact: what a subscriber that wants decisions reads, and what ``ros2 topic hz``
counts at the contact rate); the provisional (anytime) estimates cut before it, from shorter
windows, have a topic of their own, ``/extsense/contact_estimate/provisional`` (same type, with
``provisional`` set), read by those that want an early guess: the tap marker, the view, and the
behaviours or the monitor when asked to (``accept_provisional``, ``show_provisional``). The
inference node publishes them on its relative ``contact_estimate`` and
``contact_estimate/provisional``.
"""

from __future__ import annotations

NS = "/extsense"
TOPIC_EVENTS = f"{NS}/nuskin/events"
TOPIC_FRAMES = f"{NS}/biotac/frames"
TOPIC_WINDOW = f"{NS}/contact_window"
TOPIC_ESTIMATE = f"{NS}/contact_estimate"
TOPIC_PROVISIONAL_ESTIMATE = f"{TOPIC_ESTIMATE}/provisional"
TOPIC_GROUND_TRUTH = f"{NS}/ground_truth"
TOPIC_TAP_MARKER = f"{NS}/tap_marker"
TOPIC_MOTION_START = f"{NS}/motion_start"
TOPIC_HANDOVER_OFFER = f"{NS}/handover/offer"
TOPIC_DIAGNOSTICS = "/diagnostics"
TOPIC_NUSKIN_PACKETS = f"{NS}/nuskin/packets"
TOPIC_BIOTAC_PACKETS = f"{NS}/biotac/packets"

SENSOR_STREAMS: dict[str, tuple[str, str]] = {
    "nuskin": ("events", TOPIC_EVENTS),
    "biotac": ("frames", TOPIC_FRAMES),
}
"""Sensor -> the driver's relative output topic and its absolute name."""

SENSOR_PACKETS: dict[str, str] = {"nuskin": TOPIC_NUSKIN_PACKETS, "biotac": TOPIC_BIOTAC_PACKETS}
"""Sensor -> the absolute name of its driver's raw packets (``SensorPacket``, relative
``packets``): what the window node reads and bags record (docs/runtime.md, Raw packets)."""

ESTIMATE_REMAPS: tuple[tuple[str, str], ...] = (
    ("contact_estimate", TOPIC_ESTIMATE),
    ("contact_estimate/provisional", TOPIC_PROVISIONAL_ESTIMATE),
)
"""The remappings of a node that publishes or reads both estimate topics under their relative
names (a remapping matches a whole name: ``contact_estimate`` does not carry its
``/provisional`` along)."""
