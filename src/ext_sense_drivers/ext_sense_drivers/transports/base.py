"""The transport interface and the record it returns."""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple, Protocol, runtime_checkable


class Chunk(NamedTuple):
    """Bytes that arrived together.

    Attributes:
        data: The bytes, possibly empty (nothing arrived before the timeout).
        t_ns: Host arrival time, integer nanoseconds of ``time.monotonic_ns`` (or the clock the
            transport was given); taken right after the read returned.
    """

    data: bytes
    t_ns: int


class LinkState(IntEnum):
    """Where a :class:`~ext_sense_drivers.transports.reader.StreamReader` link stands."""

    STOPPED = 0
    CONNECTING = 1
    CONNECTED = 2
    BACKOFF = 3
    EXHAUSTED = 4
    """A finite source (file) reached its end; nothing more will come."""


@runtime_checkable
class Transport(Protocol):
    """A byte source. Not thread-safe: one reader thread owns it."""

    @property
    def description(self) -> str:
        """Port, bus or path; used as the diagnostics ``hardware_id``."""
        ...

    @property
    def exhausted(self) -> bool:
        """True when a finite source has delivered everything (always False for devices)."""
        ...

    def open(self) -> None:
        """Open the source.

        Raises:
            TransportError: The device or file is not there or cannot be opened.
        """
        ...

    def read(self, timeout_s: float) -> Chunk:
        """Wait up to ``timeout_s`` for bytes and return what arrived (maybe nothing).

        Raises:
            TransportError: The source is not open, or vanished while reading.
        """
        ...

    def close(self) -> None:
        """Release the source; safe to call twice or after a failure."""
        ...
