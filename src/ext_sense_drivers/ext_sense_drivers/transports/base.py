"""The transport interface and the record it returns."""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple, Protocol, runtime_checkable


class Chunk(NamedTuple):
    """Bytes that arrived together (maybe none), and when the read returned (monotonic ns)."""

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
        """Open the source (raises :class:`TransportError` when it cannot)."""
        ...

    def read(self, timeout_s: float) -> Chunk:
        """What arrived within ``timeout_s`` (raises :class:`TransportError` if it vanished)."""
        ...

    def close(self) -> None:
        """Release the source; safe to call twice or after a failure."""
        ...
