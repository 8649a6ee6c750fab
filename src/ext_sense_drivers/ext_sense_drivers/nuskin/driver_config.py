"""The NUSkin driver's settings, checked and turned into a transport and a decoding path.

Kept out of the node so the choices are validated and testable without rclpy; the node only
reads its parameters into a :class:`DriverConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_drivers.nuskin.errors import NuskinError
from ext_sense_drivers.nuskin.streams import AcesLineStream, EventStream, WordStream
from ext_sense_drivers.nuskin.wire import FlagPolarity
from ext_sense_drivers.transports.base import Transport


class TransportKind(IntEnum):
    """Where the bytes come from."""

    SERIAL = 0
    CAN = 1
    FILE = 2


class Mode(IntEnum):
    """What the bytes are."""

    WORDS = 0
    """The receiver's 4-byte event words."""
    ACES_LINE = 1
    """Raw ACES line samples (int16 little-endian, one per chip)."""


def _choice(name: str, value: str, enum: type[IntEnum]) -> IntEnum:
    names = [m.name.lower() for m in enum]
    if value.lower() not in names:
        raise NuskinError(f"The '{name}' parameter must be one of {names}. Got {value!r} instead.")
    return enum[value.upper()]


@dataclass(frozen=True)
class DriverConfig:
    """Driver settings (units in the names; see ``config/nuskin_driver.yaml``)."""

    transport: str = "serial"
    port: str = "/dev/ttyACM0"
    baud: int = 4_000_000
    can_interface: str = "socketcan"
    can_channel: str = "can0"
    can_arbitration_id: int = 0x100
    can_extended_id: bool = False
    file_path: str = ""
    file_pace: str = "recorded"
    file_bytes_per_s: float = 0.0
    file_loop: bool = False
    mode: str = "words"
    flag_polarity: str = "ignore"
    aces_threshold: float = 0.5

    @property
    def transport_kind(self) -> TransportKind:
        """The transport as an enum.

        Raises:
            NuskinError: Not serial, can or file.
        """
        return _choice("transport", self.transport, TransportKind)  # type: ignore[return-value]

    @property
    def mode_kind(self) -> Mode:
        """The mode as an enum.

        Raises:
            NuskinError: Not words or aces_line.
        """
        return _choice("mode", self.mode, Mode)  # type: ignore[return-value]

    @property
    def hardware_id(self) -> str:
        """What diagnostics show as the hardware id."""
        kind = self.transport_kind
        if kind == TransportKind.SERIAL:
            return self.port
        if kind == TransportKind.CAN:
            return f"{self.can_interface}:{self.can_channel}#{self.can_arbitration_id:#x}"
        return self.file_path

    def file_rate(self) -> float | None:
        """Replay rate of a file in bytes/s, or ``None`` for flat out.

        ``file_bytes_per_s > 0`` wins; else ``file_pace`` ``flat`` is flat out, ``recorded``
        takes the rate of a lab capture from its ``.tact`` markers, ``serial`` the 8N1 line
        rate at ``baud``.

        Raises:
            NuskinError: Unknown pace, or no ``.tact`` beside the capture for ``recorded``.
        """
        if self.file_bytes_per_s > 0:
            return float(self.file_bytes_per_s)
        pace = self.file_pace.lower()
        if pace == "flat":
            return None
        if pace == "serial":
            return self.baud / 10.0
        if pace == "recorded":
            from ext_sense_drivers.nuskin.tact import recorded_rate

            return recorded_rate(Path(self.file_path))
        raise NuskinError(
            "The 'file_pace' parameter must be one of ['recorded', 'flat', 'serial']. "
            f"Got {self.file_pace!r} instead."
        )

    def make_transport(self) -> Transport:
        """The configured byte source (not opened yet).

        Raises:
            NuskinError: Bad transport choice or file settings.
            TransportError: Bad port, baud or CAN id.
        """
        kind = self.transport_kind
        if kind == TransportKind.SERIAL:
            from ext_sense_drivers.transports.serial_port import SerialTransport

            return SerialTransport(self.port, self.baud)
        if kind == TransportKind.CAN:
            from ext_sense_drivers.transports.can_bus import CanTransport

            return CanTransport(
                self.can_interface,
                self.can_channel,
                self.can_arbitration_id,
                extended=self.can_extended_id,
            )
        if not self.file_path:
            raise NuskinError("The 'file_path' parameter must name a capture. Got '' instead.")
        from ext_sense_drivers.transports.file_source import FileTransport

        return FileTransport(self.file_path, self.file_rate(), loop=self.file_loop)

    def make_stream(self) -> EventStream:
        """The configured decoding path.

        Raises:
            NuskinError: Bad mode or flag polarity, or the ACES package is not available.
        """
        if self.mode_kind == Mode.WORDS:
            polarity = _choice("flag_polarity", self.flag_polarity, FlagPolarity)
            return WordStream(FlagPolarity(polarity), ArrivalClock.for_baud(self.baud))
        try:
            return AcesLineStream(threshold=self.aces_threshold)
        except ImportError as err:
            raise NuskinError(f"The 'mode' parameter 'aces_line' is not available: {err}") from err
