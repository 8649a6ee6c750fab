"""The one exception type of the packets package."""

from __future__ import annotations


class PacketError(Exception):
    """A malformed packet (its arrays disagree), an unknown encoding or bad encoding options.

    A consumer counts the packet as dropped and says why; it never stops on one.
    """
