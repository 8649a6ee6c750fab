"""The one exception type of the transports."""

from __future__ import annotations


class TransportError(Exception):
    """The byte source could not be opened, or vanished (unplugged port, closed bus, bad path)."""
