"""Modes of the ACES line decoder."""

from __future__ import annotations

from enum import IntEnum


class DecodeMode(IntEnum):
    """How a :class:`~ext_sense_drivers.aces.decoder.LineDecoder` searches each window."""

    ONSET = 0
    """Onset-driven cancellation; the full matched filter only where the residual says it
    missed something (default: cost follows the event rate)."""

    MATCHED_FILTER = 1
    """Full matched filter with cancellation on every window (cost follows the sample rate;
    the reference the benchmark compares against)."""
