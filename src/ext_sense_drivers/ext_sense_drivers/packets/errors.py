"""The one exception type of the packets package."""

from __future__ import annotations


class PacketError(Exception):
    """A malformed packet, an unknown encoding or bad options (consumers count and go on)."""
