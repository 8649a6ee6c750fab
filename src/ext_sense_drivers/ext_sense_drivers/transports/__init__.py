"""Byte sources behind one interface: serial (pyserial), CAN (python-can) and files.

Every transport has ``open()``, ``read(timeout_s) -> Chunk`` and ``close()``; ``read`` gives the
bytes that arrived with their host arrival time (integer nanoseconds, monotonic clock) and raises
:class:`TransportError` when the device vanishes. :class:`StreamReader` runs one in a thread and
reconnects with exponential backoff. Device-specific decoders (NUSkin words, BioTac bridge) sit on
top and never see the transport.
"""

from ext_sense_drivers.transports.base import Chunk, LinkState, Transport
from ext_sense_drivers.transports.errors import TransportError

__all__ = ["Chunk", "LinkState", "Transport", "TransportError"]
