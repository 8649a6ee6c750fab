"""The parameters every driver node shares: link, reconnect backoff, stall check, autostart.

A driver's schema subclasses :class:`LinkParameters` with its own defaults, wording and fields.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from ext_sense_drivers.transports.link_config import READER_PRIORITY_RANGE, LinkConfig
from ext_sense_drivers.transports.reader import Backoff
from ext_sense_runtime.parameters import param
from ext_sense_runtime.stamps import MS

LINK_DESCRIPTIONS: Mapping[str, str] = {
    "transport": "Byte source: serial, can or file.",
    "port": "Serial device or pyserial URL.",
    "can_interface": "python-can interface.",
    "can_channel": "CAN channel on that interface.",
    "can_arbitration_id": "Arbitration id of the frames carrying the byte stream.",
    "can_extended_id": "29-bit extended id.",
    "file_path": "Capture file (transport file).",
    "file_loop": "Replay the file for ever.",
    "reader_priority": (
        "SCHED_FIFO priority of the thread that reads and stamps the device (1-99; 0 leaves "
        "the OS default). Refused (no CAP_SYS_NICE, ulimit -r 0) it falls back to nice -10 or "
        "nothing; what it got is logged once. See docs/runtime.md, Real-time priority."
    ),
}
"""Wording of the link parameters a driver does not word for its sensor."""

_RANGES: Mapping[str, tuple[float, float]] = {
    "baud": (1200, 100_000_000),
    "can_arbitration_id": (0, 0x1FFFFFFF),
    "file_bytes_per_s": (0.0, 1e9),
    "reader_priority": READER_PRIORITY_RANGE,
}

STALL_OFF = (
    " 0 turns the stall check off (a source silent when idle, as the simulator's emulated "
    "devices are)."
)
"""Ends every driver's wording of ``expected_rate_hz``."""


def link_field(name: str, default: Any, description: str = "") -> Any:
    """A read-only link parameter with its range, in the driver's wording or the shared one."""
    low, high = _RANGES.get(name, (None, None))
    wording = description or LINK_DESCRIPTIONS[name]
    return param(default, wording, low=low, high=high, read_only=True)


@dataclass(frozen=True)
class LinkParameters:
    """The shared half of a driver's parameters (its schema subclasses this)."""

    transport: str = link_field("transport", LinkConfig.transport)
    port: str = link_field("port", LinkConfig.port)
    baud: int = link_field("baud", LinkConfig.baud, "Serial line rate, bit/s.")
    can_interface: str = link_field("can_interface", LinkConfig.can_interface)
    can_channel: str = link_field("can_channel", LinkConfig.can_channel)
    can_arbitration_id: int = link_field("can_arbitration_id", LinkConfig.can_arbitration_id)
    can_extended_id: bool = link_field("can_extended_id", LinkConfig.can_extended_id)
    file_path: str = link_field("file_path", LinkConfig.file_path)
    file_bytes_per_s: float = link_field(
        "file_bytes_per_s", LinkConfig.file_bytes_per_s, "File replay rate, bytes/s."
    )
    file_loop: bool = link_field("file_loop", LinkConfig.file_loop)
    reader_priority: int = link_field("reader_priority", LinkConfig.reader_priority)
    reconnect_initial_s: float = param(
        0.1,
        "First reconnect delay after the link vanished, s (doubles per failure).",
        low=0.001,
        high=60.0,
        read_only=True,
    )
    reconnect_max_s: float = param(
        2.0, "Longest reconnect delay, s.", low=0.001, high=600.0, read_only=True
    )
    expected_rate_hz: float = param(
        0.0,
        "Least rate of the stream while the link is up, 1/s." + STALL_OFF,
        low=0.0,
        high=10_000_000.0,
        read_only=True,
    )
    stall_warn_ms: float = param(
        200.0,
        "Silence of the stream while the link is up and the node active that is a stall: WARN "
        "on /diagnostics naming the stream (at least 3 expected intervals), ms.",
        low=1.0,
        high=60_000.0,
        read_only=True,
    )
    stall_error_ms: float = param(
        500.0,
        "Silence of the stream that turns the stall ERROR (>= stall_warn_ms), ms.",
        low=1.0,
        high=60_000.0,
        read_only=True,
    )
    autostart: bool = param(
        True,
        "Configure and activate this lifecycle node at start-up (ros2 run, tests); the graphs "
        "set it false and drive the transitions themselves (launch events, ext-sense run), or "
        "leave them to an external manager (manage_drivers:=false).",
        read_only=True,
    )

    def __post_init__(self) -> None:
        if self.stall_error_ms < self.stall_warn_ms:
            raise ValueError(
                f"The 'stall_error_ms' parameter must be >= stall_warn_ms "
                f"({self.stall_warn_ms:g}). Got {self.stall_error_ms:g} instead."
            )

    def link(self) -> dict[str, Any]:
        """The link settings by ``LinkConfig`` field name."""
        return {f.name: getattr(self, f.name) for f in fields(LinkConfig)}

    def backoff(self) -> Backoff:
        """Delays from ``reconnect_initial_s`` up to the larger of the two."""
        initial = self.reconnect_initial_s
        return Backoff(initial, max(initial, self.reconnect_max_s))

    def stall_ns(self) -> tuple[int, int]:
        """The WARN and ERROR silences of the stall check, ns."""
        return round(self.stall_warn_ms * MS), round(self.stall_error_ms * MS)
