"""The live view's channels: names, encodings and JSON schemas, one place for node and layout.

Pictures and summaries the view draws live under ``/extsense/view/``; the graph's low-rate
topics pass through as CDR under their ROS names, as a bag holds them, so one layout reads a
live graph and a bag alike. The raw streams are not passed through (not a display rate).
"""

from __future__ import annotations

from typing import Any

from ext_sense.topics import NS as GRAPH_NS
from ext_sense.topics import (
    SENSOR_PACKETS,
    TOPIC_DIAGNOSTICS,
    TOPIC_ESTIMATE,
    TOPIC_GROUND_TRUTH,
    TOPIC_PROVISIONAL_ESTIMATE,
    TOPIC_WINDOW,
)
from ext_sense_bags import STANDARD_TOPICS

NS = f"{GRAPH_NS}/view"
TAXELS = f"{NS}/taxels"
RATES = f"{NS}/rates"
PAC = f"{NS}/pac"
WINDOW = f"{NS}/window"
ESTIMATE = f"{NS}/estimate"
ESTIMATE_INFO = f"{NS}/estimate_info"
DIAGNOSTICS = f"{NS}/diagnostics"

IMAGES = (TAXELS, WINDOW, ESTIMATE)
"""Channels of ``foxglove.RawImage`` (``rgb8``)."""

PASSED_THROUGH: dict[str, str] = {
    topic: STANDARD_TOPICS[topic].msgtype
    for topic in (
        TOPIC_ESTIMATE,
        TOPIC_PROVISIONAL_ESTIMATE,
        TOPIC_GROUND_TRUTH,
        TOPIC_WINDOW,
        TOPIC_DIAGNOSTICS,
    )
}
"""ROS topic -> message type of the topics the view sends on unchanged (CDR)."""


def _number() -> dict[str, Any]:
    return {"type": ["number", "null"]}


JSON_SCHEMAS: dict[str, tuple[str, dict[str, Any]]] = {
    RATES: (
        "ext_sense.view.Rates",
        {
            "type": "object",
            "description": "Event rate per NUSkin finger, events/s, smoothed over tau_s.",
            "properties": {
                "left_events_per_s": _number(),
                "right_events_per_s": _number(),
                "total_events_per_s": _number(),
                "rejected_events": {"type": "integer"},
            },
        },
    ),
    PAC: (
        "ext_sense.view.Pac",
        {
            "type": "object",
            "description": "The last second of BioTac PAC per sensor (pac_<id>), every 2nd sample.",
            "properties": {"sensor_ids": {"type": "array", "items": {"type": "integer"}}},
            "additionalProperties": {"type": "array", "items": {"type": "number"}},
        },
    ),
    ESTIMATE_INFO: (
        "ext_sense.view.Estimate",
        {
            "type": "object",
            "description": "The latest estimate in numbers, with its trial's truth when known.",
            "properties": {
                "task": {"type": "string"},
                "kind": {"type": "string", "enum": ["provisional", "final"]},
                "latency_ms": _number(),
                "post_contact_ms": _number(),
                "tap_position_cm": _number(),
                "tap_position_std_cm": _number(),
                "class_label": {"type": "string"},
                "class_names": {"type": "array", "items": {"type": "string"}},
                "class_probabilities": {"type": "array", "items": {"type": "number"}},
                "stability_probability": _number(),
                "degraded": {"type": "boolean"},
                "truth_tap_position_cm": _number(),
                "truth_class_label": {"type": "string"},
                "error_cm": _number(),
            },
        },
    ),
    DIAGNOSTICS: (
        "ext_sense.view.Diagnostics",
        {
            "type": "object",
            "description": "/diagnostics summed up: the worst level and every status not OK.",
            "properties": {
                "worst_level": {"type": "integer"},
                "worst": {"type": "string"},
                "not_ok": {"type": "array", "items": {"type": "string"}},
                "statuses": {"type": "integer"},
            },
        },
    ),
}


def view_channels(sensor: str) -> tuple[str, ...]:
    """Every channel the view advertises for a sensor (``nuskin``: rates; ``biotac``: PAC)."""
    own = (
        TAXELS,
        RATES if sensor == "nuskin" else PAC,
        WINDOW,
        ESTIMATE,
        ESTIMATE_INFO,
        DIAGNOSTICS,
    )
    return (*own, *PASSED_THROUGH)


def view_inputs(sensor: str) -> tuple[str, ...]:
    """The graph topics the view reads (packets, then those passed through): a replay's."""
    return (SENSOR_PACKETS[sensor], *PASSED_THROUGH)
