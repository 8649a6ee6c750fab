"""The link settings every driver config derives from: transport choice, serial, CAN, file."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, ClassVar, TypeVar

from ext_sense_drivers.transports.base import Transport
from ext_sense_drivers.transports.errors import TransportError

if TYPE_CHECKING:
    from ext_sense_drivers.transports.reader import Backoff, StreamReader

E = TypeVar("E", bound=IntEnum)

READER_PRIORITY_RANGE = (0, 99)
"""Range of the ``reader_priority`` parameter (Linux SCHED_FIFO priorities, 0 = leave as is)."""


class TransportKind(IntEnum):
    """Where the bytes come from."""

    SERIAL = 0
    CAN = 1
    FILE = 2


@dataclass(frozen=True)
class LinkConfig:
    """Transport settings shared by the drivers; subclasses set defaults and :attr:`error`."""

    error: ClassVar[type[Exception]] = TransportError
    """Raised for a bad transport choice or a file transport without a file."""

    transport: str = "serial"
    port: str = "/dev/ttyACM0"
    baud: int = 1_000_000
    can_interface: str = "socketcan"
    can_channel: str = "can0"
    can_arbitration_id: int = 0x100
    can_extended_id: bool = False
    file_path: str = ""
    file_bytes_per_s: float = 0.0
    file_loop: bool = False
    reader_priority: int = 0

    def choice(self, name: str, enum: type[E]) -> E:
        """The setting ``name`` as a member of ``enum`` (case-insensitive; :attr:`error` if not)."""
        value = getattr(self, name)
        names = [m.name.lower() for m in enum]
        if value.lower() not in names:
            raise self.error(
                f"The '{name}' parameter must be one of {names}. Got {value!r} instead."
            )
        return enum[value.upper()]

    @property
    def transport_kind(self) -> TransportKind:
        """The transport as an enum."""
        return self.choice("transport", TransportKind)

    @property
    def hardware_id(self) -> str:
        """What diagnostics show as the hardware id: port, ``interface:channel#id`` or path."""
        kind = self.transport_kind
        if kind == TransportKind.SERIAL:
            return self.port
        if kind == TransportKind.CAN:
            return f"{self.can_interface}:{self.can_channel}#{self.can_arbitration_id:#x}"
        return self.file_path

    def check_link(self) -> None:
        """Raise :attr:`error` for an unknown transport or a file transport without a file."""
        if self.transport_kind == TransportKind.FILE and not self.file_path:
            raise self.error("The 'file_path' parameter must name a capture. Got '' instead.")

    def file_rate(self) -> float | None:
        """Replay rate of a file in bytes/s: ``file_bytes_per_s`` if > 0, else ``None`` (flat)."""
        return float(self.file_bytes_per_s) if self.file_bytes_per_s > 0 else None

    def make_reader(self, backoff: Backoff | None = None) -> StreamReader:
        """A reader thread (not started) for the configured source, at ``reader_priority``."""
        from ext_sense_drivers.transports.reader import StreamReader

        low, high = READER_PRIORITY_RANGE
        if not low <= int(self.reader_priority) <= high:
            raise self.error(
                f"The 'reader_priority' parameter must be in [{low}, {high}]. "
                f"Got {self.reader_priority} instead."
            )
        return StreamReader(
            self.make_transport(), backoff=backoff, priority=int(self.reader_priority)
        )

    def make_transport(self) -> Transport:
        """The configured byte source, not opened (:attr:`error` or TransportError if bad)."""
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
        self.check_link()
        from ext_sense_drivers.transports.file_source import FileTransport

        return FileTransport(self.file_path, self.file_rate(), loop=self.file_loop)
