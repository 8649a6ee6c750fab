"""The BioTac driver's settings, checked and turned into a transport and a clock model.

Kept out of the node so the choices are validated and testable without rclpy; the node only
reads its parameters into a :class:`BioTacDriverConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

from ext_sense_drivers.biotac.bridge import MAX_SENSORS, STANDARD_FRAME_SIZE
from ext_sense_drivers.biotac.clock import FRAME_PERIOD_NS, FrameClock, transmission_ns
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.transports.base import Transport


class TransportKind(IntEnum):
    """Where the bridge bytes come from."""

    SERIAL = 0
    CAN = 1
    FILE = 2


@dataclass(frozen=True)
class BioTacDriverConfig:
    """Driver settings (units in the names; see ``config/biotac_driver.yaml``)."""

    transport: str = "serial"
    port: str = "/dev/ttyACM0"
    baud: int = 1_000_000
    can_interface: str = "socketcan"
    can_channel: str = "can0"
    can_arbitration_id: int = 0x200
    can_extended_id: bool = False
    file_path: str = ""
    file_bytes_per_s: float = 0.0
    file_loop: bool = False
    frame_id_prefix: str = "biotac_"
    expected_sensors: tuple[int, ...] = field(default=(0,))
    latency_ns: int = 0
    clock_window_frames: int = 200

    def __post_init__(self) -> None:
        kinds = [k.name.lower() for k in TransportKind]
        if self.transport.lower() not in kinds:
            raise BioTacError(
                f"The 'transport' parameter must be one of {kinds}. Got {self.transport!r} instead."
            )
        bad = [s for s in self.expected_sensors if not 0 <= int(s) < MAX_SENSORS]
        if bad:
            raise BioTacError(
                f"The 'expected_sensors' parameter must hold slots 0..{MAX_SENSORS - 1}. "
                f"Got {list(self.expected_sensors)} instead."
            )
        if self.transport_kind == TransportKind.FILE and not self.file_path:
            raise BioTacError("The 'file_path' parameter must name a capture. Got '' instead.")

    @property
    def transport_kind(self) -> TransportKind:
        """The transport as an enum."""
        return TransportKind[self.transport.upper()]

    @property
    def hardware_id(self) -> str:
        """What diagnostics show as the hardware id."""
        kind = self.transport_kind
        if kind == TransportKind.SERIAL:
            return self.port
        if kind == TransportKind.CAN:
            return f"{self.can_interface}:{self.can_channel}#{self.can_arbitration_id:#x}"
        return self.file_path

    def frame_id(self, sensor_id: int) -> str:
        """``header.frame_id`` of a sensor slot."""
        return f"{self.frame_id_prefix}{int(sensor_id)}"

    @property
    def lead_ns(self) -> int:
        """First sample to least-delayed arrival: frame span + serial transmission + latency."""
        lead = FRAME_PERIOD_NS + int(self.latency_ns)
        if self.transport_kind == TransportKind.SERIAL:
            lead += transmission_ns(STANDARD_FRAME_SIZE, self.baud)
        return lead

    def make_clock(self) -> FrameClock:
        """A fresh clock model for one sensor."""
        return FrameClock(FRAME_PERIOD_NS, self.lead_ns, self.clock_window_frames)

    def make_transport(self) -> Transport:
        """The configured byte source (not opened yet).

        Raises:
            TransportError: Bad port, baud, CAN id or file rate.
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
        from ext_sense_drivers.transports.file_source import FileTransport

        rate = self.file_bytes_per_s if self.file_bytes_per_s > 0 else None
        return FileTransport(self.file_path, rate, loop=self.file_loop)
