"""The graphs' topic names, in one place: the graph descriptions, the view and the commands.

Nodes use relative names, remapped by the graph descriptions to these absolute ones (types and
QoS in :data:`ext_sense_bags.STANDARD_TOPICS`). ``contact_estimate`` carries one final estimate
per contact; the provisional (anytime) ones have their own ``contact_estimate/provisional``.
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

SENSOR_PACKETS: dict[str, str] = {"nuskin": TOPIC_NUSKIN_PACKETS, "biotac": TOPIC_BIOTAC_PACKETS}
"""Sensor -> its driver's raw packets (``SensorPacket``, relative ``packets``)."""

ESTIMATE_REMAPS: tuple[tuple[str, str], ...] = (
    ("contact_estimate", TOPIC_ESTIMATE),
    ("contact_estimate/provisional", TOPIC_PROVISIONAL_ESTIMATE),
)
"""Both estimate topics' remappings (one does not carry the other's ``/provisional`` along)."""
