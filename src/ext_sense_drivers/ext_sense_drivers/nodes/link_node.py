"""The link half every driver node shares: parameters, reader thread, stream publisher, diagnostics.

The NUSkin and BioTac driver nodes read a byte link (serial, CAN or file) through a
:class:`~ext_sense_drivers.transports.reader.StreamReader` and differ only in what they decode.
These helpers declare the link and reconnect parameters the same way in both, build the sensor
stream publisher with its QoS event counters, report the link state on ``/diagnostics`` and stop
the reader. What each sensor decodes, stamps and publishes stays in its own node.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher

from ext_sense_drivers.transports.base import LinkState
from ext_sense_drivers.transports.link_config import LinkConfig
from ext_sense_drivers.transports.reader import Backoff, StreamReader
from ext_sense_runtime.diagnostics import Level
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.qos import SENSOR_STREAM_QOS
from ext_sense_runtime.qos_events import QosEventCounter

LINK_DESCRIPTIONS: Mapping[str, str] = {
    "transport": "Byte source: serial, can or file.",
    "port": "Serial device or pyserial URL.",
    "can_interface": "python-can interface.",
    "can_channel": "CAN channel on that interface.",
    "can_arbitration_id": "Arbitration id of the frames carrying the byte stream.",
    "can_extended_id": "29-bit extended id.",
    "file_path": "Capture file (transport file).",
    "file_loop": "Replay the file for ever.",
}
"""Descriptions of the link parameters a node does not word for its sensor (``baud`` and
``file_bytes_per_s`` it always words itself)."""

_RANGES: Mapping[str, tuple[float, float]] = {
    "baud": (1200, 100_000_000),
    "can_arbitration_id": (0, 0x1FFFFFFF),
    "file_bytes_per_s": (0.0, 1e9),
}

_LINK_PARAMETERS = (
    "transport",
    "port",
    "baud",
    "can_interface",
    "can_channel",
    "can_arbitration_id",
    "can_extended_id",
    "file_path",
    "file_bytes_per_s",
    "file_loop",
)


def declare_link_parameters(
    node: Node, defaults: LinkConfig, descriptions: Mapping[str, str]
) -> dict[str, Any]:
    """Declare the read-only link parameters (``transport`` ... ``file_loop``).

    Args:
        node: The driver node.
        defaults: The driver's config with its defaults (they fix each parameter's type).
        descriptions: The node's wording of ``baud`` and ``file_bytes_per_s`` (with units), and
            of any other link parameter it words differently from :data:`LINK_DESCRIPTIONS`.

    Returns:
        The values after overrides, by parameter name (the config's field names).

    Raises:
        KeyError: ``descriptions`` lacks ``baud`` or ``file_bytes_per_s``.
    """
    wording = {**LINK_DESCRIPTIONS, **descriptions}
    values: dict[str, Any] = {}
    for name in _LINK_PARAMETERS:
        low, high = _RANGES.get(name, (None, None))
        values[name] = declare(
            node,
            name,
            getattr(defaults, name),
            wording[name],
            low=low,
            high=high,
            read_only=True,
        )
    return values


def declare_backoff(node: Node, lost: str, *, max_read_only: bool = True) -> Backoff:
    """Declare ``reconnect_initial_s`` and ``reconnect_max_s`` and return the backoff they give.

    Args:
        node: The driver node.
        lost: What vanishes in the wording (``"port"``, ``"link"``).
        max_read_only: Whether ``reconnect_max_s`` is read-only (a node that lets it change
            validates the change in its own on-set callback).

    Returns:
        Delays from ``reconnect_initial_s`` up to ``max(reconnect_initial_s, reconnect_max_s)``.
    """
    initial_s = declare(
        node,
        "reconnect_initial_s",
        0.1,
        f"First reconnect delay after the {lost} vanished, s (doubles per failure).",
        low=0.001,
        high=60.0,
        read_only=True,
    )
    max_s = declare(
        node,
        "reconnect_max_s",
        2.0,
        "Longest reconnect delay, s.",
        low=0.001,
        high=600.0,
        read_only=max_read_only,
    )
    return Backoff(initial_s, max(initial_s, max_s))


def monotonic_to_ros_ns(node: Node) -> int:
    """Offset from monotonic host ns (the transports' arrival times) to the node's ROS time ns.

    Taken once at start, so stamps never step back when the wall clock is adjusted.
    """
    return node.get_clock().now().nanoseconds - time.monotonic_ns()


def create_stream_publisher(
    node: Node, msg_type: type, topic: str
) -> tuple[Publisher, QosEventCounter]:
    """A raw sensor stream publisher (``SENSOR_STREAM_QOS``) whose QoS events are counted.

    Returns:
        The publisher and the counter that :func:`link_status` reports.
    """
    qos_events = QosEventCounter()
    pub = node.create_publisher(
        msg_type, topic, SENSOR_STREAM_QOS, event_callbacks=qos_events.publisher()
    )
    return pub, qos_events


def link_status(
    reader: StreamReader, lost: str, values: Mapping[str, object]
) -> tuple[Level, str, dict[str, object]]:
    """The ``link`` diagnostics check: reader state and counters, then the node's ``values``.

    OK while connected or when a capture file has been replayed to its end, ERROR while the
    reader backs off after a failure, WARN otherwise (connecting, stopped).

    Args:
        reader: The node's reader.
        lost: What is unavailable in the message (``"port"``, ``"link"``).
        values: Further key-values (what the node published, its QoS event counts).
    """
    state = reader.state
    report: dict[str, object] = {
        "port_state": state.name.lower(),
        "connects": reader.connects,
        "disconnects": reader.disconnects,
        "open_failures": reader.open_failures,
        "bytes_total": reader.bytes_total,
        "dropped_bytes": reader.dropped_bytes,
        "last_error": reader.last_error,
        **values,
    }
    if state == LinkState.CONNECTED:
        return Level.OK, "connected", report
    if state == LinkState.EXHAUSTED:
        return Level.OK, "capture file replayed to its end", report
    if state == LinkState.BACKOFF:
        return Level.ERROR, f"{lost} unavailable, retrying: {reader.last_error}", report
    return Level.WARN, state.name.lower(), report


def stop_reader(node: Node) -> None:
    """Stop the node's ``reader`` thread (closing the link), if the constructor got that far."""
    reader = getattr(node, "reader", None)
    if reader is not None:
        reader.stop()
