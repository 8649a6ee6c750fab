"""Modes of the ACES line decoder."""

from __future__ import annotations

from enum import IntEnum


class DecodeMode(IntEnum):
    """How a :class:`~ext_sense_drivers.aces.decoder.LineDecoder` searches each window."""

    ONSET = 0
    """Onset-driven cancellation, the matched filter only where something was missed."""

    MATCHED_FILTER = 1
    """Matched filter on every window (the benchmark's reference)."""
