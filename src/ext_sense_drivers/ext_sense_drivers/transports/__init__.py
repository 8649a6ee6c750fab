"""Byte sources behind one interface (serial, CAN, files) and the reconnecting reader thread."""

from ext_sense_drivers.transports.base import Chunk, LinkState, Transport
from ext_sense_drivers.transports.errors import TransportError

__all__ = ["Chunk", "LinkState", "Transport", "TransportError"]
